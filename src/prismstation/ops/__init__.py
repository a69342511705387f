"""The application layer: every use case once, as functions over the model with one
progress-and-cancel protocol (:mod:`prismstation.ops.progress`). ``cli/`` and ``gui/`` are thin
adapters over these (an import-linter contract keeps ``cli/`` from calling ``core/`` itself).

Modules: :mod:`~.project` (create a project from a scene, points and measurements),
:mod:`~.fit` (fit and residual report), :mod:`~.orient_dem` (orientation from a reference
DEM, no GCP; :mod:`~.coarse_offsets` its first step), :mod:`~.dsm_export` (the DSM export of
the ``dsm`` command and the window) over :mod:`~.dsm` (the engine, coarse to fine) and
:mod:`~.dsm_tiles` (its Dask tiles), :mod:`~.coregister` (DEM-to-DEM co-registration),
:mod:`~.transfer` (point transfer, automatic tie points), :mod:`~.predict` (where a point
should be in each view, with its ellipse), :mod:`~.validate` (DSM against a reference DSM),
:mod:`~.rectify` (single-image rectification), :mod:`~.resection` (frame-camera resection,
B/H), :mod:`~.reference_heights` (a reference DEM as heights for the window),
:mod:`~.progress` (the protocol).

Results that can fail are falsy with a ``reason`` (:mod:`prismstation.core.adjustment.estimate`);
bad input raises :class:`~prismstation.errors.InputError`.

Layers, imports pointing down only: ``cli`` → ``gui`` → ``ops`` → ``io`` → ``model`` → ``core``.
"""
