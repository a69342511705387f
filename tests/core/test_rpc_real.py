"""The RPC bias fit on real Pléiades imagery: the triplet (Aubagne), the Giza pair (.geom RPCs,
crops placed by their geotransforms) and the Réunion pair.

Tie points are matched automatically; one image is held fixed. Along-track stereo cannot tell
a shift of an image along its lines from a change of every point's height, so the fit takes
reference heights: no DEM covering these crops is among the samples, so they are the heights
the products' own RPCs give the tie points (their intersection without bias), with 2 m of
noise drawn per point and a σ of 2 m — a reference DEM whose common offset to the RPCs is zero.
(A real DEM's common offset δh moves the fitted line bias by δh·(B/H)/GSD pixels.)
"""
from __future__ import annotations

import numpy as np
import pytest
import rasterio

from prismstation.core.models.rpc_adjust import adjust, adjust_snooping
from prismstation.core.models.rpc_bias import intersect_points
from prismstation.core.matching.rpc_tiepoints import match_tie_points
from prismstation.io.rpc import read_rpc

SETS = {"triplet": [f"pleiades_triplet/img_0{i}.tif" for i in (1, 2, 3)],
        "gizeh": ["pleiades_pair_gizeh/img1.tif", "pleiades_pair_gizeh/img2.tif"],
        "reunion": ["pleiades_pair_reunion/img_01.tif", "pleiades_pair_reunion/img_02.tif"]}
H_SIGMA = 2.0


class Block:
    def __init__(self, root, files):
        self.rpcs = [read_rpc(root / f) for f in files]
        images = []
        for f in files:
            with rasterio.open(root / f) as ds:
                images.append(ds.read(1))
        self.tp = tp = match_tie_points(images, cell=48)   # ~half the points of the benchmark
        self.before = intersect_points(self.rpcs, tp.point, tp.image, tp.xy, tp.sigma, tp.n_points)
        rng = np.random.default_rng(0)
        self.href = self.before.h + rng.normal(0, H_SIGMA, tp.n_points)
        self.fit, self.kept = adjust_snooping(
            self.rpcs, tp.point, tp.image, tp.xy, tp.sigma, bias="shift",
            height_point=np.arange(tp.n_points), height=self.href, height_sigma=H_SIGMA)

    def fit_subset(self, rpcs, points):
        """Fit with ``rpcs`` on the kept points in ``points`` (indices of the input's points)."""
        tp = self.tp
        sel = np.isin(tp.point, points)
        new = np.full(tp.n_points, -1)
        new[points] = np.arange(len(points))
        return adjust(rpcs, new[tp.point[sel]], tp.image[sel], tp.xy[sel], tp.sigma[sel],
                      bias="shift", n_points=len(points), height_point=np.arange(len(points)),
                      height=self.href[points], height_sigma=H_SIGMA,
                      centres=[(m.x0, m.y0) for m in self.fit.models])


@pytest.fixture(scope="module", params=list(SETS))
def block(request, shared_data):
    return request.param, Block(shared_data, SETS[request.param])


def rms(a):
    return np.sqrt(np.mean(np.square(a), axis=0))


def test_tie_points_and_residuals_before_and_after(block):
    name, b = block
    tp, fit = b.tp, b.fit
    assert tp.n_points >= 100, tp.n_points
    assert b.kept.mean() > 0.95                       # data snooping rejects few points
    assert fit.fixed == (0,) and 0.3 < fit.sigma0 < 1.0  # the matcher's σ is not optimistic
    for k in range(len(b.rpcs)):
        before = rms(b.before.residuals[tp.image == k])
        after = fit.rms_by_image()[k]
        assert np.all(after < 0.15), (name, k, after)
        # across the lines (x) the raw RPCs disagree by tenths of a pixel; the bias removes it
        assert after[0] < 0.5 * before[0], (name, k, before, after)


@pytest.mark.parametrize("component, offset", [("line", 30.0), ("line", -45.0),
                                                ("sample", 30.0), ("sample", -45.0)])
def test_known_offset_recovered(block, component, offset):
    """Move the last image's RPC line (or sample) offset by tens of pixels: the shift bias fitted
    on each of three disjoint thirds of the tie points finds it back, relative to the
    unperturbed fit on all of them, within the tie points' σ and within 3 formal σ."""
    name, b = block
    k = len(b.rpcs) - 1
    c = 1 if component == "line" else 0
    moved = list(b.rpcs)
    moved[k] = b.rpcs[k].shifted(**({"dy": offset} if c else {"dx": offset}))
    truth = b.fit.models[k].params[c] - offset
    tie_sigma = float(np.median(b.tp.sigma[b.tp.image == k, c]))
    points = np.flatnonzero(b.kept)
    for part in np.array_split(np.random.default_rng(1).permutation(points), 3):
        res = b.fit_subset(moved, np.sort(part))
        err = res.models[k].params[c] - truth
        sigma = res.bias_std(k)[c]
        assert abs(err) < tie_sigma and abs(err) < 3 * sigma, (name, err, sigma, tie_sigma)
