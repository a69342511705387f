"""The sensor-model protocol (``core/models/sensor.py``) as every registered model implements it: the
fitted geometry takes arrays of any leading shape (a grid, as an orthoimage asks for it) and
gives the same shape, image → ground inverts ground → image, and a scene names its model."""
from __future__ import annotations

import numpy as np
import pytest

from prismstation.core.models import sensors
from prismstation.core.models.rpc_bias import RpcBias
from prismstation.core.models.rpc_model import RpcModel, RpcView
from prismstation.core.models.scene import Scene
from prismstation.core.models.sensor import SensorModel
from prismstation.core.models.solution import solve
from prismstation.io.rpc_scene import LonLatProjection
from prismstation.sim.model_triplet import make_points, make_scene
from tests.ops.rpc_synth import make_rpc

LON0, LAT0 = 3.0, 43.3   # the synthetic RPC images' centre (UTM 31)


def prism_model():
    sc = make_scene(size=6000)
    return solve(sc, make_points(sc, n_gcp=9, n_icp=5, seed=1)).model, np.array([540000.0, 4560000.0])


def rpc_model():
    projection = LonLatProjection("EPSG:32631")
    views = {f"img{k}": RpcView(f"img{k}", make_rpc(LON0, LAT0, tan_along=t, seed=k + 1), projection, 2.0,
                                shape=(500, 500)) for k, t in enumerate((-0.2, 0.0, 0.25))}
    scene = Scene("EPSG:32631", None, None, views, sensor=RpcModel)
    bias = {v: RpcBias("affine", [1.5, 0.3, -0.2, -4.0, 0.1, 0.5], None, 250.0, 250.0) for v in views}
    E, N = projection.from_lonlat(LON0, LAT0)
    return RpcModel(scene, bias), np.array([float(E), float(N)])


@pytest.mark.parametrize("make", [prism_model, rpc_model], ids=["prism", "rpc"])
def test_fitted_geometry_on_a_grid_is_the_geometry_point_by_point(make):
    model, centre = make()
    assert isinstance(model, SensorModel) and sensors.MODELS[model.name] is type(model)
    E, N = np.meshgrid(centre[0] + np.linspace(-300, 300, 7), centre[1] + np.linspace(-200, 200, 5))
    en = np.stack([E, N], axis=-1)                          # (5, 7, 2): an orthoimage's grid
    h = 300.0 + 0.05 * (E - centre[0])                      # (5, 7)
    for v in model.scene.views:
        xy = model.ground_to_image(v, en, h)
        assert xy.shape == (5, 7, 2)
        one = np.array([model.ground_to_image(v, en[i, j], h[i, j]) for i in range(5) for j in range(7)])
        np.testing.assert_allclose(xy.reshape(-1, 2), one.reshape(-1, 2), rtol=0, atol=1e-9)
        back = model.image_to_ground(v, xy, h)
        assert back.shape == (5, 7, 2)
        np.testing.assert_allclose(back, en, rtol=0, atol=1e-4)   # metres
        assert model.fitted(v)


def test_a_scene_names_its_sensor_model():
    sc = make_scene(size=2000)
    with pytest.raises(TypeError, match="sensor model"):
        Scene(sc.crs, sc.satellite_altitude_m, sc.track, sc.views)
    assert list(sensors.MODELS) == ["prism", "rpc"] and sensors.model_named("rpc") is RpcModel
