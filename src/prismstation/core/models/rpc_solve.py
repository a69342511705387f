"""The RPC model's fit of a project (:meth:`prismstation.core.models.rpc_model.RpcModel.fit`): every image's bias by the
bias-compensated block adjustment of :mod:`prismstation.core.models.rpc_adjust` (Grodecki & Dial 2003;
Fraser & Hanley 2003) on the GCPs and the tie points (and, after an orientation from a
reference DEM, each bias's a-priori value: :class:`BiasPrior`), then every point evaluated as the
PRISM model's fit evaluates them.

What enters the adjustment: GCPs measured in one image or more (their known ground weighted
by the survey's σ; exact — :data:`GCP_EXACT_SIGMA_M` — where none is given) and tie points
measured in two or more. Check points never do. Without GCPs one view is held fixed
(``settings.fixed_view``, default the reference view) and the others' biases are relative to
its RPC. Tie points are held to the reference DEM's heights (with its σ) where the GCPs are
fewer than the bias model needs (:func:`dem_needed`): in along-track stereo a bias along the
lines is a height, which tie points alone cannot tell.

What each point gets: a GCP or check point its ground from its own rays through the fitted
model (multi-ray intersection; one ray meets the reference DEM, else the mean height), so that
its ground residual checks the model; a tie point of the adjustment its adjusted ground.
σ of an intersection: each ray's a-priori σ scaled by the adjustment's σ0, with the fitted
bias's σ at that point added. Residuals (measured − predicted, px) are taken against the known
ground of GCPs and check points and the estimated ground of tie points; every observation of
the adjustment has its redundancy number and externally studentised residual; a point's largest,
on the normal scale (:func:`~prismstation.core.models.solution.normal_equivalent`), beyond
``settings.blunder_threshold`` flags it as a blunder, as in the PRISM fit.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from prismstation.core.adjustment.estimate import FailedFit
from prismstation.core.adjustment.lsq import LsqResult
from prismstation.core.models.ray_dem import ray_meets_surface
from prismstation.core.models.rpc_adjust import adjust
from prismstation.core.models.results import PointResult
from prismstation.core.models.rpc_bias import BIAS_MODELS, BIAS_NAMES, RpcBias, intersect_points
from prismstation.core.models.solution import Control, Settings, normal_equivalent
from prismstation.errors import DegenerateGeometry, ModelError

#: σ (m) of a GCP's ground when its survey gives none: taken as exact
GCP_EXACT_SIGMA_M = 1e-3
#: the bias models tried, most parameters first, when the requested one is not determined
LADDER = ("affine", "shift_drift", "shift")
#: a-priori σ of the bias parameters (Grodecki & Dial 2003's a-priori covariance of the
#: adjustment parameters): the constant terms ``a0``, ``b0`` in pixels — the RPCs of current
#: pushbroom products locate within about 10 m (Pléiades 8.5 m CE90, WorldView-3 3.5 m CE90)
#: — and the linear terms in pixels per 1,000 pixels. Where the data determine a parameter
#: (σ of tenths of a pixel) the prior moves it by ~(σ/10)² of its value; where they do not (a
#: shift along the lines with tie points only) it holds the parameter near zero with this σ.
APRIORI_SHIFT_PX = 10.0
APRIORI_LINEAR_PX = 2.0
#: a parameter whose σ is more than this fraction of its a-priori σ is reported as not
#: determined by the data
UNDETERMINED = 0.5


def apriori_sigma(kind: str) -> np.ndarray:
    """``(p,)`` a-priori σ of the ``kind`` bias's parameters (:data:`APRIORI_SHIFT_PX`,
    :data:`APRIORI_LINEAR_PX`)."""
    return np.array([APRIORI_SHIFT_PX if n.endswith("0") else APRIORI_LINEAR_PX for n in BIAS_NAMES[kind]])


def dem_needed(n_gcp: int, kind: str) -> bool:
    """Whether tie points need the reference DEM's heights: fewer GCPs than the ``kind`` bias
    needs (half its parameters per view, at least one)."""
    return BIAS_MODELS[kind] > 0 and n_gcp < max(1, math.ceil(BIAS_MODELS[kind] / 2))


class BlockFit(NamedTuple):
    """What :func:`fit_block` gives: the points as the adjustment took them (``block``, a
    :class:`_Block`, which evaluates every point), each view's :class:`RpcBias`, the adjustment
    (:class:`~prismstation.core.models.rpc_adjust.RpcAdjustment`, or None when nothing was fitted), the
    messages and the failures (view → falsy ``FailedFit``); ``undetermined`` view → the names
    of the parameters the data left at their a-priori σ (:func:`undetermined`); ``held`` how
    many tie points were held to the reference DEM's heights."""

    block: "_Block"
    bias: dict
    result: object
    messages: list
    failures: dict
    undetermined: dict = {}
    held: int = 0


def fit_block(scene, points, settings: Settings = Settings(), *, height_of=None,
              height_sigma_m: float | None = None, control: Control | None = None) -> BlockFit:
    """Fit every view's bias to ``points`` (:class:`~prismstation.core.models.solution.PointObs`;
    module docstring). ``height_of``: the reference DEM's ellipsoidal heights at map points
    ``(n, 2)`` → ``(n,)``, ``height_sigma_m`` their σ (without it tie points are not held to
    them, and a message says so). ``control``: its ``part`` view → :class:`BiasPrior`, each
    view's bias known a priori (an orientation from a reference DEM): its parameters are
    observed at those values with their σ and no view is held fixed unless
    ``settings.fixed_view`` names one. Each view's bias model is ``settings.bias_of(view)``;
    ``settings.use_gcps`` False fits without the GCPs (they are then checked as check points
    are). ``height_sigma_m`` is a number or a function of map points ``(n, 2)`` → ``(n,)`` m (a
    σ per point, as :func:`prismstation.ops.reference_heights.height_sigma` makes it). Raises
    :class:`ModelError` only for settings this model does not have (an unknown bias model or
    view); data the operator can fix are messages."""
    kinds = {v: settings.bias_of(v) for v in scene.views}
    for k in set(kinds.values()) | {settings.bias_model}:
        if k not in BIAS_MODELS:
            raise ModelError(f"bias model {k!r} is not one the RPC model offers ({', '.join(BIAS_MODELS)})")
    unknown = sorted(set(dict(settings.view_bias)) - set(scene.views))
    if unknown:
        raise ModelError(f"a bias model is set for views the scene does not have: {', '.join(unknown)}")
    kind = max(kinds.values(), key=BIAS_MODELS.get)   # the most parameters any view has
    if settings.fixed_view is not None and settings.fixed_view not in scene.views:
        raise ModelError(f"the view held fixed, {settings.fixed_view!r}, is not a view of the scene "
                         f"({', '.join(scene.views)})")
    points = list(points)
    names = list(scene.views)
    run = _Block(scene, points, settings)
    messages: list[str] = []
    failures: dict = {}
    ref = scene.reference_view
    prior = _priors(None if control is None else control.part, names, kind, messages)
    fixed_name = settings.fixed_view or (ref if not run.gcps and kind != "none" and not prior else None)
    fixed = () if fixed_name is None else (names.index(fixed_name),)
    if not run.gcps and settings.fixed_view is None and kind != "none" and run.block and not prior:
        messages.append(f"no GCP: view {ref} held fixed; the other views' biases are relative to its RPC")
    use_dem = height_of is not None and dem_needed(len(run.gcps), kind)
    if use_dem and prior:
        # the orientation from the reference DEM carries what the DEM says: holding the tie
        # points to it again would count it twice (and the σ would shrink for nothing)
        use_dem = False
        messages.append("tie points not held to the reference DEM: the orientation from a reference DEM "
                        "carries it already")
    if use_dem and not (callable(height_sigma_m) or (height_sigma_m is not None and height_sigma_m > 0)):
        use_dem = False
        messages.append("the reference DEM's heights come without their σ: tie points are not held to "
                        "them (the DEM places only points seen in one image)")

    bias = {v: RpcBias(fixed=names.index(v) in fixed) for v in names}
    result, held = None, np.zeros(0, bool)
    if not run.block:
        if kind != "none":
            reason = "nothing to fit: no GCP measured and no tie point measured in two images"
            messages.append(reason)
            failures[ref] = FailedFit(ModelError(reason))
    else:
        reason = ""
        for m in [kind] if kind == "none" else [k for k in LADDER if BIAS_MODELS[k] <= BIAS_MODELS[kind]]:
            per_view = [min(kinds[v], m, key=BIAS_MODELS.get) for v in names]
            try:
                result, held = run.adjust(per_view, fixed, height_of if use_dem else None, height_sigma_m,
                                          _prior_as(prior, per_view))
            except DegenerateGeometry as exc:
                reason = str(exc)
                continue
            except ModelError as exc:
                reason = str(exc)
                break
            if m != kind:
                messages.append(f"the {kind} bias is not determined ({reason}): {m} fitted instead")
            break
        if result is None:
            hint = ("; tie points alone cannot tell a shift along the lines from a height: add GCPs, "
                    "a reference DEM, or hold a view fixed" if not run.gcps else "")
            messages.append(f"RPC bias fit: {reason}{hint}")
            failures[ref] = FailedFit(DegenerateGeometry(reason) if "determined" in reason else ModelError(reason))
        else:
            bias = run.biases(result, m, fixed)
            weak = undetermined(bias, result)
            messages += _undetermined(weak, bool(run.gcps) or bool(held.any()) or bool(prior))
            if held.any():
                hs = (f"σ {height_sigma_m:.1f} m" if not callable(height_sigma_m) else
                      f"σ {run.held_sigma[0]:.1f}–{run.held_sigma[1]:.1f} m with the slopes")
                messages.append(f"{int(held.sum())} tie points held to the reference DEM's heights "
                                f"({hs}): fewer GCPs than the {m} bias needs")
            return BlockFit(run, bias, result, messages, failures, weak, int(held.sum()))
    return BlockFit(run, bias, result, messages, failures)


class _Block:
    """The points of one fit as the adjustment takes them: ``block`` the GCPs (measured once or
    more) and tie points (measured twice or more), indexed in that order."""

    def __init__(self, scene, points, settings: Settings):
        self.scene, self.settings = scene, settings
        self.names = list(scene.views)
        self.projection = next(iter(scene.views.values())).projection
        self.points = points
        self.seen = {p.id: [v for v in self.names if v in p.image and np.all(np.isfinite(p.image[v]))]
                     for p in points}
        self.gcps = [p for p in points if p.kind == "GCP" and p.ground is not None and self.seen[p.id]
                     and settings.use_gcps]
        self.held_sigma = (math.nan, math.nan)  # the smallest and largest σ of held heights (m)
        ties = [p for p in points if p.kind == "TIE" and len(self.seen[p.id]) >= 2]
        self.block = self.gcps + ties
        P, I, XY, S = [], [], [], []
        for i, p in enumerate(self.block):
            for v in self.seen[p.id]:
                P.append(i)
                I.append(self.names.index(v))
                XY.append(p.image[v])
                S.append(p.sigma_px.get(v, settings.sigma_px))
        self.point, self.image = np.array(P, int), np.array(I, int)
        self.xy, self.sigma = np.array(XY, float).reshape(-1, 2), np.array(S, float)
        g = np.array([p.ground for p in self.gcps], float).reshape(-1, 3)
        lon, lat = self.projection.to_lonlat(g[:, 0], g[:, 1])
        self.gcp_llh = np.column_stack([lon, lat, g[:, 2]])
        self.gcp_sigma = np.array([_ground_sigma(p.sigma_ground) for p in self.gcps], float).reshape(-1, 3)

    def adjust(self, kind, fixed, height_of, height_sigma, prior=None):
        """The adjustment with the ``kind`` bias (one name, or one per view); with ``height_of``
        the tie points are held to the DEM's heights (σ ``height_sigma``: metres, or a function
        of map points), taken again where the adjusted points moved (three rounds at most);
        ``prior``: view index → :class:`BiasPrior` in that view's ``kind``'s parameters.
        Returns ``(RpcAdjustment, held (n,) bool)``."""
        n, g = len(self.block), len(self.gcps)
        rpcs = [self.scene.views[v].rpc for v in self.names]
        centres = np.array([self.xy[self.image == k].mean(0) if np.any(self.image == k) else (0.0, 0.0)
                            for k in range(len(self.names))])
        for k, p in (prior or {}).items():
            centres[k] = (p.x0, p.y0)
        common = dict(bias=kind, fixed=fixed, n_points=n, gcp_point=np.arange(g), gcp_llh=self.gcp_llh,
                      gcp_sigma=self.gcp_sigma, bias_sigma=apriori_sigma, centres=centres,
                      bias_prior={k: (p.params, p.sigma) for k, p in (prior or {}).items()})
        held = np.zeros(n, bool)
        if height_of is None:
            return adjust(rpcs, self.point, self.image, self.xy, self.sigma, **common), held
        # where the raw RPCs put the tie points (the GCPs at their known heights)
        hc = np.full(n, np.nan)
        hc[:g] = self.gcp_llh[:, 2]
        first = intersect_points(rpcs, self.point, self.image, self.xy, self.sigma, n, height=hc,
                                 height_sigma=np.where(np.isfinite(hc), GCP_EXACT_SIGMA_M, np.nan))
        lon, lat, res = first.lon, first.lat, None
        href = np.full(n, np.nan)
        for _ in range(3):
            E, N = self.projection.from_lonlat(lon[g:], lat[g:])
            new = np.full(n, np.nan)
            new[g:] = np.asarray(height_of(np.column_stack([E, N])), float)
            if res is not None and np.array_equal(np.isfinite(new), held) and \
                    np.nanmax(np.abs(new - href), initial=0.0) < 0.01:
                break
            href, held = new, np.isfinite(new)
            hs = height_sigma
            if callable(height_sigma):
                s = np.full(n, np.nan)
                s[g:] = np.asarray(height_sigma(np.column_stack([E, N])), float)
                hs = s[held]
                if hs.size:
                    self.held_sigma = (float(np.min(hs)), float(np.max(hs)))
            res = adjust(rpcs, self.point, self.image, self.xy, self.sigma, height_point=np.flatnonzero(held),
                         height=href[held], height_sigma=hs, **common)
            lon, lat = res.lon, res.lat
        return res, held

    def biases(self, res, kind, fixed) -> dict:
        """Each view's :class:`RpcBias` with its share of the adjustment as an ``LsqResult``."""
        out = {}
        s0 = res.sigma0 if res.dof > 0 and math.isfinite(res.sigma0) else None
        for k, v in enumerate(self.names):
            sel = self.image == k
            m = res.models[k]
            share = LsqResult(m.params, res.bias_cov[k], s0, res.dof, res.residuals[sel].ravel(),
                              res.redundancy[sel].ravel(), res.std_residuals[sel].ravel())
            out[v] = RpcBias(m.kind, m.params, res.bias_cov[k], m.x0, m.y0, k in fixed, share)
        return out

    # ------------------------------------------------------------------ every point
    def evaluate(self, model, res, height_of, settings):
        """The :class:`PointResult` of every point through the fitted ``model`` (an
        :class:`~prismstation.core.models.rpc_model.RpcModel`), and the mean height."""
        pts, proj = self.points, self.projection
        n = len(pts)
        est = np.full((n, 3), np.nan)
        sig = np.full((n, 3), np.nan)
        source = [None] * n
        index = {p.id: i for i, p in enumerate(pts)}
        s0 = res.sigma0 if res is not None and res.dof > 0 and math.isfinite(res.sigma0) else 1.0
        # tie points of the adjustment: their adjusted ground
        if res is not None:
            for j, p in enumerate(self.block):
                if p.kind == "TIE":
                    i = index[p.id]
                    E, N = proj.from_lonlat(res.lon[j:j + 1], res.lat[j:j + 1])
                    est[i] = (E[0], N[0], res.h[j])
                    sig[i] = np.sqrt(np.clip(np.diag(res.point_cov[j]), 0.0, None))
                    source[i] = "intersection"
        # the others seen twice or more: intersected through the fitted model
        multi = [i for i, p in enumerate(pts) if source[i] is None and len(self.seen[p.id]) >= 2]
        self._intersect(model, multi, est, sig, source, s0)
        known = np.array([p.ground if p.ground is not None else (np.nan,) * 3 for p in pts], float).reshape(n, 3)
        mean_h = _mean_height(settings, self.gcps, known, est, self.scene)
        # seen once: the ray meets the DEM, else the mean height
        for i, p in enumerate(pts):
            if source[i] is None and self.seen[p.id]:
                v = self.seen[p.id][0]
                xy = np.asarray(p.image[v], float)
                h, src = mean_h, "mean"
                if height_of is not None:
                    hit = ray_meets_surface(lambda hh: model.image_to_ground(v, xy, hh[0])[None],
                                            lambda e: np.asarray(height_of(e), float), mean_h)
                    if hit:
                        h, src = float(hit.h[0]), "reference"
                en = model.image_to_ground(v, xy, h)
                if np.all(np.isfinite(en)):
                    est[i], source[i] = (en[0], en[1], h), src
        return self._results(model, res, est, sig, source, known, settings), mean_h

    def _intersect(self, model, idx, est, sig, source, s0):
        """Multi-ray intersection of the points ``idx`` through ``model``: each ray's σ is its
        a-priori σ × σ0 with the fitted bias's σ at the point added."""
        if not idx:
            return
        P, I, XY, S = [], [], [], []
        for j, i in enumerate(idx):
            p = self.points[i]
            for v in self.seen[p.id]:
                xy = np.asarray(p.image[v], float)
                c = model.bias_cov(v, xy)
                s = p.sigma_px.get(v, self.settings.sigma_px) * s0
                P.append(j), I.append(self.names.index(v)), XY.append(xy)
                S.append(np.sqrt(s * s + np.diag(c)))
        models = [model.models[v] for v in self.names]
        P, I, XY, S = np.array(P), np.array(I), np.array(XY), np.array(S)
        try:
            parts = [(np.arange(len(idx)), intersect_points(models, P, I, XY, S, len(idx)))]
        except ModelError:       # one bad point: the others one by one
            parts = []
            for j in range(len(idx)):
                sel = P == j
                try:
                    parts.append((np.array([j]), intersect_points(models, P[sel] * 0, I[sel], XY[sel], S[sel], 1)))
                except ModelError:
                    pass
        for js, r in parts:
            E, N = self.projection.from_lonlat(r.lon, r.lat)
            for k, j in enumerate(js):
                i = idx[j]
                est[i] = (E[k], N[k], r.h[k])
                sig[i] = np.sqrt(np.clip(np.diag(r.cov[k]), 0.0, None))
                source[i] = "intersection"

    def _results(self, model, res, est, sig, source, known, settings) -> list:
        pts, names = self.points, self.names
        n = len(pts)
        has_known = np.all(np.isfinite(known), axis=1)
        g = np.where(has_known[:, None], known, est)
        ok = np.all(np.isfinite(g), axis=1)
        pred = {v: np.full((n, 2), np.nan) for v in names}
        for v in names:
            if ok.any():
                pred[v][ok] = model.ground_to_image(v, g[ok, :2], g[ok, 2])
        # the adjustment's tests, per point of the block: the largest externally studentised
        # residual of its observations on the normal scale; every point beyond the threshold
        # is a blunder, as in the PRISM fit
        tests = {}
        if res is not None:
            z = normal_equivalent(res.std_residuals, res.dof)
            for j, p in enumerate(self.block):
                sel = self.point == j
                zs = z[sel]
                s = float(np.nanmax(zs)) if np.isfinite(zs).any() else math.nan
                tests[p.id] = (s, float(res.redundancy[sel].min()))
        out = []
        for i, p in enumerate(pts):
            seen = self.seen[p.id]
            measured = {v: tuple(map(float, p.image[v])) for v in seen}
            predicted = {v: tuple(map(float, pred[v][i])) for v in names if np.all(np.isfinite(pred[v][i]))}
            residual = {}
            if has_known[i] or (p.kind == "TIE" and len(seen) >= 2):
                residual = {v: (measured[v][0] - predicted[v][0], measured[v][1] - predicted[v][1])
                            for v in seen if v in predicted}
            e = tuple(map(float, est[i])) if np.all(np.isfinite(est[i])) else None
            gres = tuple(float(a - b) for a, b in zip(e, known[i])) if e and has_known[i] else None
            s, red = tests.get(p.id, (math.nan, None))
            note = ("not measured in any view" if not seen else
                    f"measured in one image: height from the {'reference DEM' if source[i] == 'reference' else 'mean height'}"
                    if len(seen) == 1 else "")
            sg = tuple(map(float, sig[i])) if e and np.all(np.isfinite(sig[i])) else None
            out.append(PointResult(p.id, p.kind, measured, predicted, residual, None, {}, e,
                                   source[i] if e else None, gres, s if math.isfinite(s) else None, red,
                                   math.isfinite(s) and s > settings.blunder_threshold, note, sg))
        return out


class BiasPrior(NamedTuple):
    """A view's bias known a priori (an orientation from a reference DEM): the ``model``'s
    ``params`` with their ``sigma`` (same units), at the reference point ``(x0, y0)`` px."""

    model: str
    params: tuple
    sigma: tuple
    x0: float
    y0: float


def _priors(control, names, kind, messages) -> dict:
    """``control`` (view → :class:`BiasPrior`, or None) by view index; a message says so."""
    if not control:
        return {}
    unknown = sorted(set(control) - set(names))
    if unknown:
        raise ModelError(f"the a-priori biases name views the scene does not have: {', '.join(unknown)}")
    if kind != "none":
        messages.append("biases a priori from the orientation on a reference DEM (" + ", ".join(
            f"{v}: " + ", ".join(f"{n} {p:+.2f} ± {s:.2f}" for n, p, s in zip(BIAS_NAMES[b.model], b.params, b.sigma))
            for v, b in control.items()) + "); no view held fixed: the block's datum is the reference's")
    return {names.index(v): BiasPrior(*b) for v, b in control.items()}


def control_from_record(scene, record: dict) -> Control:
    """Each view's a-priori bias (:class:`BiasPrior`) from a project's saved ``dem_control``
    record (``prismstation.ops.rpc_project.orientation_record``), as a :class:`Control`; a
    malformed one is a ``KeyError``, ``TypeError`` or ``ValueError``."""
    if record.get("sensor") != "rpc":
        raise ValueError("not the record of an orientation of images with RPCs")
    out = {}
    for v, b in record["biases"].items():
        if v not in scene.views or b["model"] not in BIAS_MODELS:
            raise ValueError(f"view {v!r} or bias model {b['model']!r} unknown")
        p, s = tuple(map(float, b["params"])), tuple(map(float, b["sigma"]))
        if not (len(p) == len(s) == len(BIAS_NAMES[b["model"]])) or not all(map(math.isfinite, p + s)):
            raise ValueError(f"view {v}: {len(p)} parameters for the {b['model']} bias")
        out[v] = BiasPrior(b["model"], p, s, float(b["x0"]), float(b["y0"]))
    return Control("the orientation on a reference DEM", out)


def _prior_as(prior: dict, kinds) -> dict:
    """The a-priori biases in the parameters of ``kinds`` (one name, or one per view index): a
    parameter the prior has keeps its value and σ, another is 0 with :func:`apriori_sigma`."""
    out = {}
    for k, b in prior.items():
        kind = kinds if isinstance(kinds, str) else kinds[k]
        have = dict(zip(BIAS_NAMES[b.model], zip(b.params, b.sigma)))
        base = dict(zip(BIAS_NAMES[kind], apriori_sigma(kind)))
        vals = [have.get(n, (0.0, base[n])) for n in BIAS_NAMES[kind]]
        out[k] = BiasPrior(kind, tuple(v[0] for v in vals), tuple(max(float(v[1]), MIN_PRIOR_SIGMA_PX) for v in vals),
                           b.x0, b.y0)
    return out


#: the smallest σ an a-priori bias parameter is given (px): a co-registration's formal σ of a few
#: hundredths would otherwise freeze the bias against the tie points
MIN_PRIOR_SIGMA_PX = 0.05


def undetermined(bias: dict, res) -> dict:
    """View → the names of its bias parameters the data leave at their a-priori σ (σ over σ0
    beyond :data:`UNDETERMINED` of :func:`apriori_sigma`): their value is the prior's, not a
    measurement. Views held fixed and views with none are left out."""
    s0 = res.sigma0 if res.dof > 0 and math.isfinite(res.sigma0) and res.sigma0 > 0 else 1.0
    out = {}
    for v, b in bias.items():
        if b.fixed or not b.names:
            continue
        ratio = b.std / s0 / apriori_sigma(b.model)
        weak = tuple(n for n, r in zip(b.names, ratio) if r > UNDETERMINED)
        if weak:
            out[v] = weak
    return out


def _undetermined(weak: dict, controlled: bool) -> list[str]:
    """Messages naming the parameters of :func:`undetermined`."""
    out = []
    for v, weak in weak.items():
        if weak:
            hint = ("" if controlled else ": tie points alone cannot tell a shift along the lines from a "
                    "height; add GCPs or a reference DEM")
            out.append(f"view {v}: {', '.join(weak)} not determined by the data (held near 0 by the "
                       f"a-priori σ){hint}")
    return out


def _ground_sigma(s) -> tuple:
    """``(σE, σN, σh)`` m of a GCP's survey σ ``(σ plan, σ h)``; exact where not given."""
    plan, h = (None, None) if s is None else s
    plan = plan if plan is not None and plan > 0 else GCP_EXACT_SIGMA_M
    h = h if h is not None and h > 0 else GCP_EXACT_SIGMA_M
    return (plan, plan, h)


def _mean_height(settings, gcps, known, est, scene) -> float:
    """The height of points nothing else places: the setting, else the GCPs' mean, else the
    known points', else the intersected points', else the RPCs' height offset."""
    if settings.mean_height is not None:
        return float(settings.mean_height)
    if gcps:
        return float(np.mean([p.ground[2] for p in gcps]))
    for h in (known[:, 2], est[:, 2]):
        h = h[np.isfinite(h)]
        if h.size:
            return float(h.mean())
    return float(np.mean([v.rpc.h_off for v in scene.views.values()]))
