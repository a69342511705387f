"""Matching images and surfaces: point transfer (:mod:`.matching`, least-squares matching in
:mod:`.lsm`, :mod:`.lsm_search`, :mod:`.lsm_sigma`, :mod:`.lsm_spline`), searches over an
a-priori range (:mod:`.coarse`), DEM-to-DEM surface matching (:mod:`.coreg`), dense and
semi-global matching (:mod:`.dense`, :mod:`.sgm`), tie points of an RPC block
(:mod:`.rpc_tiepoints`) and the JPEG block-noise filter (:mod:`.deblock`)."""
