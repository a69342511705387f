"""The application layer: every use case once (fit, orient from a DEM, DSM, transfer, validate,
rectify, reference heights), as functions over the model with one progress-and-cancel protocol
(:mod:`prismstation.ops.progress`). ``cli/`` and ``gui/`` are thin adapters over these.

Layers, imports pointing down only: ``gui``/``cli`` → ``ops`` → ``io`` → ``model`` → ``core``.
"""
