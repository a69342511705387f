"""Sensor models: the one protocol (:mod:`.sensor`), the models by name (:mod:`.sensors`), the
result types every fit shares (:mod:`.solution`, :mod:`.results`) and each model whole — the
empirical PRISM model (:mod:`.prism`, :mod:`.prism_model`), the RPC model with its bias and
block adjustment (:mod:`.rpc`, :mod:`.rpc_bias`, :mod:`.rpc_adjust`, :mod:`.rpc_solve`,
:mod:`.rpc_model`), the classic single-image transforms and resection (:mod:`.rectify`,
:mod:`.resection`); the scene as the models see it (:mod:`.scene`) and rays meeting a
surface (:mod:`.ray_dem`)."""
