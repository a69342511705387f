"""The synthetic pushbroom images with RPCs of the RPC tests: :mod:`prismstation.sim.rpc_synth`
(in the package, so that the benchmarks use it too)."""
from prismstation.sim.rpc_synth import World, analytic_terrain, dem_terrain, make_rpc, render, write_image  # noqa: F401
