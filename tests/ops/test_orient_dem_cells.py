"""The matched patches' cells enter the adjustment under their own patch, failed patches or not."""
import numpy as np

from prismstation.ops.dem_patches import PatchCells
from prismstation.ops.orient_dem import join_cells


def _patch(k, n):
    cells = {} if n == 0 else {key: np.full(n, float(k)) for key in ("x", "y", "e", "n", "h")}
    if n:
        cells.update(row=np.arange(n), col=np.zeros(n, int))
    return PatchCells((0, 0, 1, 1), 0.0, 0.0, 0.5, cells, "" if n else "failed")


def test_failed_patches_do_not_shift_the_others():
    pcs = [_patch(0, 12), _patch(1, 0), _patch(2, 0), _patch(3, 20), _patch(4, 15)]
    cells, index = join_cells(pcs)
    assert index == [0, 3, 4]
    assert sorted(set(cells.patch.tolist())) == [0, 1, 2]          # 0 … n − 1, as the adjustment counts
    for j, k in enumerate(index):                                  # adjustment patch j holds pcs[k]'s cells
        sel = cells.patch == j
        assert sel.sum() == pcs[k].count and np.all(cells.h[sel] == k)


def test_the_prior_is_taken_where_the_field_puts_n():
    """With N's shift field known, a patch's prior heights are the reference where N really
    looks (at the ancillary point plus (dE, dN)), minus dh: in the ancillary frame, the frame of
    the relative DEM's heights. Without it, where the ancillary model puts N."""
    from types import SimpleNamespace
    from prismstation.core.models import prism
    from prismstation.ops.dem_patches import ReferenceGrid
    from prismstation.sim.model_triplet import make_scene

    sc = make_scene(size=2000)
    posting = 30.0
    lo, hi = np.array([530000.0, 4550000.0]), np.array([550000.0, 4570000.0])
    n = int((hi[0] - lo[0]) / posting)
    e = lo[0] + (np.arange(n) + 0.5) * posting
    nn = hi[1] - (np.arange(n) + 0.5) * posting
    heights = (800 + 0.3 * (e[None, :] - 540000) + 300 * np.sin((nn[:, None] - 4560000) / 700)).astype(np.float32)
    ref = ReferenceGrid(SimpleNamespace(heights=heights), lo, hi, posting, 800.0, heights, None, (3.0, 3.0))
    rng = np.random.default_rng(2)
    xy = rng.uniform(100, 1900, (60, 2))
    shift = lambda x, y: np.stack([np.full_like(x, 60.0), -45.0 + 0.01 * y, np.full_like(x, 7.0)], -1)  # noqa: E731
    hit = ref.ground(sc, xy, shift)
    assert hit.converged.all()
    s = shift(xy[:, 0], xy[:, 1])
    np.testing.assert_allclose(hit.en, prism.ancillary_to_ground(sc, sc.views["N"], xy, hit.h), atol=1e-6)
    np.testing.assert_allclose(hit.h, ref.at(heights, hit.en + s[:, :2]) - s[:, 2], atol=0.05)
    plain = ref.ground(sc, xy)
    np.testing.assert_allclose(plain.h, ref.at(heights, plain.en), atol=0.05)
    assert np.abs(plain.h - hit.h).max() > 20.0       # 75 m on slopes of up to 0.5: tens of metres


def test_the_dense_prior_holds_no_reference_noise(tmp_path):
    """The matcher's sub-pixel value is drawn toward its prior: a prior that holds the
    reference's cell-to-cell noise prints it into the relative DEMs, whose gradients then share
    the reference's noise and count as relief (on another simulator's smooth hills under a 4 m
    noise SRTM-like reference: ρ 0.030 where the true terrain's was 0.006, the field's σ 4 ×
    short of its error). The prior is the reference smoothed over two of its cells: its noise
    is a fraction of the reference's, the relief kept."""
    from types import SimpleNamespace
    import rasterio
    from rasterio.transform import from_origin
    from prismstation.ops.dem_patches import read_reference
    from prismstation.sim.model_triplet import make_scene

    sc = make_scene(size=2000)
    cell = 90.0
    w0, n0, n = 528000.0, 4572000.0, 260
    e = w0 + (np.arange(n) + 0.5) * cell
    nn = n0 - (np.arange(n) + 0.5) * cell
    relief = 800 + 60 * np.sin((e[None, :] - w0) / 1500) * np.cos((nn[:, None] - n0) / 1800)
    noise = np.random.default_rng(3).normal(0, 4.0, relief.shape)
    path = tmp_path / "ref.tif"
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs=sc.crs, transform=from_origin(w0, n0, cell, cell)) as dst:
        dst.write((relief + noise).astype(np.float32), 1)
    run = SimpleNamespace(scene=sc, posting_m=30.0, shape=sc.views["N"].shape, radius_m=150.0,
                          reference_path=path, geoid=None)
    ref = read_reference(run)
    xy = np.random.default_rng(4).uniform(200, 1800, (400, 2))
    plain, smooth = ref.ground(sc, xy), ref.ground(sc, xy, smooth=True)
    truth = lambda en: 800 + 60 * np.sin((en[:, 0] - w0) / 1500) * np.cos((en[:, 1] - n0) / 1800)  # noqa: E731
    err_plain, err_smooth = plain.h - truth(plain.en), smooth.h - truth(smooth.en)
    assert np.std(err_plain) > 2.5                      # the reference's noise, read bilinearly
    assert np.std(err_smooth) < 0.3 * np.std(err_plain)
    assert abs(np.mean(err_smooth)) < 0.5               # the relief (60 m over kilometres) kept
