"""What the DEM orientation's patches cannot check (ops/dem_unchecked.py): where the adjustment
was started, on synthetic cells whose truth is known."""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from prismstation.core.orientation import conditioning as cond
from prismstation.core.orientation.field_adjust import adjust_field
from prismstation.core.orientation.field_model import Surface
from prismstation.ops.dem_unchecked import add_to_covariances, start_term

from tests.core.test_field_adjust import BASIS, POST, PRIOR, SIZE, make_cells, terrain

LATTICE = cond.lattice((SIZE, SIZE))
NORTH = np.array([0.0, 1.0])


def _sigma_and_error(surf, cells, P, truth, start):
    """The field adjusted from ``start``; its planimetric σ without and with the start term,
    the term, and its planimetric error (RMS at the lattice)."""
    refit = lambda th: adjust_field(cells, surf, BASIS, th, n_patches=P, prior_sigma=PRIOR)  # noqa: E731
    fit = refit(start)
    assert fit, fit.reason
    covs = np.array([fit.cov_at(a, b) for a, b in zip(*LATTICE)])
    before = cond.summarise(covs, NORTH).plan
    term = start_term(fit, refit, POST, PRIOR[0])
    note = add_to_covariances(covs, BASIS, {"start": term}, *LATTICE, NORTH)
    err = fit.field(*LATTICE)[:, :2] - BASIS.predict(truth, *LATTICE)[:, :2]
    return before, cond.summarise(covs, NORTH).plan, term, float(np.sqrt(np.mean(np.sum(err ** 2, 1)))), note


def test_a_field_that_stays_where_it_is_started_says_so_and_its_sigma_covers_it():
    """Hills of about 12 m over kilometres under a reference with 4 m of white noise per 30 m
    post: the noise, sampled bilinearly, ripples the cost with the posts' period and the
    relief's trend is too weak to leave a ripple's basin, so Gauss–Newton stays near its start
    (as on another simulator's 10 km scene, where the whole mosaic's search had put it 40 m
    off). Started 120 m off, the field ends about 70 m off at a stated σ of about 27 m (2.6 σ);
    the start term sees the field follow its start and its σ, the a-priori 50 m times that
    response, covers the error."""
    rng = np.random.default_rng(3)
    n = 600
    hills = ndimage.gaussian_filter(rng.normal(size=(n, n)), 30)
    hills = 12.0 * hills / hills.std()
    true = Surface(hills + 500.0, 0.0, n * POST, POST)
    noisy = Surface(true.heights + rng.normal(0, 4.0, (n, n)), 0.0, n * POST, POST)
    truth = np.zeros(9)
    cells, P = make_cells(true, truth, grid=4, side=32, noise=0.3, seed=1)
    start = truth + np.r_[120.0, 0, 0, 0, 0, 0, 0, 0, 0]
    before, after, term, err, note = _sigma_and_error(noisy, cells, P, truth, start)
    assert err > 2 * before                   # without the term: a confident wrong answer
    assert np.abs(np.diag(term["k"])).max() > 0.5 and not term["reason"]
    assert err <= 2 * after, (err, after)
    assert "it follows its start" in note and "where the adjustment was started" in note


def test_relief_brings_the_field_back_and_the_start_term_stays_small():
    """On relief that fixes the field the adjustment returns from a start one post away: the
    term is a small share of the σ (the project's own scenes keep their σ)."""
    surf = terrain(seed=5)
    truth = np.array([12.0, 2.0, -1.5, -7.0, 0.5, 1.0, 3.0, -0.8, 0.4])
    cells, P = make_cells(surf, truth, grid=4, side=16, noise=1.0, seed=2)
    before, after, term, err, note = _sigma_and_error(surf, cells, P, truth, np.zeros(9))
    assert np.abs(np.asarray(term["k"])).max() < 0.02, term["k"]
    assert after < 1.2 * before and err <= 2 * after
    assert "follows its start" not in note
