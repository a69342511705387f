"""The sensor models this program knows, by the name a scene file gives (``"model"`` of its
views): the one place a model is registered in ``core/``. The scene reader picks the class
here (:attr:`Scene.sensor <prismstation.core.models.scene.Scene.sensor>`); ``ops/sensors.py`` and
``gui/sensors.py`` hold each model's workflows and widgets under the same name."""
from __future__ import annotations

from prismstation.core.models.prism_model import PrismModel
from prismstation.core.models.rpc_model import RpcModel

#: name → sensor model class (:class:`~prismstation.core.models.sensor.SensorModel`)
MODELS = {PrismModel.name: PrismModel, RpcModel.name: RpcModel}
#: the model of a scene whose views name none
DEFAULT = PrismModel.name


def model_named(name: str):
    """The sensor model class called ``name`` (a ``KeyError`` for an unknown one)."""
    return MODELS[name]
