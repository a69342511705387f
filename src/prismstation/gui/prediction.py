"""The views' predictions (:mod:`prismstation.ops.predict`) kept for the current solution.

:class:`Predictions` recomputes them when a solution is published or the reference DEM
changes; the known ground of the project (heights made ellipsoidal through its geoid) is kept
until a ground point or the geoid changes, so a click costs the predictions only.
"""
from __future__ import annotations

from prismstation.errors import PrismError
from prismstation.ops.predict import (DEFAULT_DEM_SIGMA_M, DEFAULT_HEIGHT_SPREAD_M, dem_sigma,
                                      height_spread, known_ground, predict_all, project_inputs)


class Predictions:
    """``{id: {view: Prediction}}`` of one project under one solution (``self.by_point``)."""

    def __init__(self):
        self.by_point: dict = {}
        self._ground_key = None
        self._ground: dict = {}
        self.sigma_dem = DEFAULT_DEM_SIGMA_M       # of the reference DEM, measured at the points
        self.sigma_mean = DEFAULT_HEIGHT_SPREAD_M  # of the mean height: the known heights' spread

    def update(self, project, solution, height_of=None) -> dict:
        """Recompute for ``solution`` of ``project`` (None: none); returns :attr:`by_point`."""
        if project is None or solution is None or not solution.ok:
            self.by_point = {}
            return self.by_point
        key = (id(project), repr(project.geoid),
               tuple(p for p in project.points.values() if p.kind != "TIE"))
        if key != self._ground_key:
            try:
                self._ground = known_ground(project)
            except PrismError:  # the geoid does not cover the points: the fit says so too
                self._ground = {}
            self._ground_key = key
        self.sigma_dem = dem_sigma(height_of, self._ground)
        self.sigma_mean = height_spread(g[2] for g in self._ground.values())
        self.by_point = predict_all(solution, project_inputs(project, self._ground),
                                    height_of=height_of, ground=self._ground)
        return self.by_point

    def get(self, pid: str, view: str):
        return self.by_point.get(pid, {}).get(view)
