"""The application layer: every use case once (fit, orient from a DEM, DSM, transfer, validate,
rectify, reference heights), as functions over the model with one progress-and-cancel protocol
(:mod:`prismstation.ops.progress`). ``cli/`` and ``gui/`` are thin adapters over these.

Modules: :mod:`~.fit` (fit and residual report), :mod:`~.orient_dem` (orientation from a
reference DEM, no GCP), :mod:`~.transfer` (point transfer, automatic tie points),
:mod:`~.validate` (DSM against a reference DSM), :mod:`~.rectify` (single-image
rectification), :mod:`~.reference_heights` (a reference DEM as heights for the window),
:mod:`~.progress` (the protocol). The DSM is still :mod:`prismstation.io.dsm` until it moves.

Layers, imports pointing down only: ``gui``/``cli`` → ``ops`` → ``io`` → ``model`` → ``core``.
"""
