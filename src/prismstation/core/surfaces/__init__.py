"""Heights on grids: a DSM tile from a pair (:mod:`.stereo_tile`; RPC pairs on local epipolar
lines, :mod:`.rpc_epipolar`), which heights it follows (:mod:`.dsm_heights`), the grid maths
(:mod:`.dsm_grid`), DSM − reference statistics (:mod:`.dsmstats`), an orthoimage tile
(:mod:`.ortho`), sampling a grid at scattered points (:mod:`.sample`)."""
