"""The scenes of the point-transfer benchmarks (``bench_transfer.py``, ``bench_transfer_minima.py``):
``(terrain, seed, centre (lon, lat) or None[, simulate's options])`` by set — the ones the
matcher was tuned on, and the ones judged on and never tuned on."""

#: the scenes the matcher was tuned on; sets judged on first and then looked at (after
#: "seen" the σ got its term across the parallax — z across 1.3–1.4 on the fractal relief, as
#: on the tuning set; after "seen2" a single view's match over a wide band must be confirmed
#: and a shape may not shear across the parallax — two wrong matches there without a DEM;
#: after "seen3" the position along the parallax got its weighted fit and the search without a
#: DEM its slope from the first view found — 60 of 70 found there); and scenes never looked at
#: before their figures were taken ("judged")
SETS = {
    "tuning": [("fractal", 3, None), ("smooth", 3, None), ("dem", 2, (5.214, 44.533))],
    "seen": [("fractal", 11, None), ("smooth", 11, None), ("dem", 1, (5.217, 44.233)),
             ("dem", 4, (5.696, 44.708))],
    "seen2": [("fractal", 12, None), ("smooth", 12, None), ("dem", 5, (5.88, 44.48)),
              ("dem", 6, (5.28, 44.83))],
    "seen3": [("fractal", 13, None), ("smooth", 13, None), ("dem", 7, (5.63, 44.48)),
              ("dem", 8, (5.43, 44.43))],
    # the two steepest 10 km squares of the tile (mean slope 35–37 % on SRTM's 90 m) at least
    # 0.12° from the scenes above and clear of its voids
    "judged": [("fractal", 23, None), ("smooth", 23, None), ("dem", 24, (5.35, 44.20)),
               ("dem", 25, (5.90, 44.85))],
    # the simulator's options for what another renderer differs by (tuning): each pixel one
    # point of the ground (no point spread: edges alias), flat parcels with hard edges, 2 DN of
    # noise, JPEG block noise; and real relief (a place of the SRTM tile tuned on before) so drawn
    "options": [("smooth", 31, None, dict(texture="parcels", psf_px=0.0, noise_dn=2.0)),
                ("fractal", 32, None, dict(texture="parcels", psf_px=0.0, noise_dn=2.0)),
                ("dem", 35, (5.63, 44.48), dict(texture="parcels", psf_px=0.0, noise_dn=2.0)),
                # the same scene against the other renderer's kind of reference: 3″ geographic,
                # EGM96, 4 m of noise (its figure of the relief within a template is mostly noise)
                ("dem", 35, (5.63, 44.48), dict(texture="parcels", psf_px=0.0, noise_dn=2.0,
                                                reference="geographic")),
                # parcels as another renderer draws them (larger, of lower contrast, a faint grain
                # inside: ``simulate --texture mottled``), on smooth hills and on the steep relief
                ("smooth", 36, None, dict(texture="mottled", psf_px=0.0, noise_dn=2.0)),
                ("dem", 37, (5.63, 44.48), dict(texture="mottled", psf_px=0.0, noise_dn=2.0)),
                ("dem", 37, (5.63, 44.48), dict(texture="mottled", psf_px=0.0, noise_dn=2.0,
                                                reference="geographic")),
                ("smooth", 33, None, dict(psf_px=0.0, noise_dn=2.0)),
                ("smooth", 34, None, dict(jpeg_quality=75))],
    # the other renderer's kind of parcels on steep relief at the two places of "judged" (never
    # tuned on with this texture), against both kinds of reference: judges the steep targets
    "judged_mottled": [(*place, dict(texture="mottled", psf_px=0.0, noise_dn=2.0, **ref))
                       for place in (("dem", 41, (5.35, 44.20)), ("dem", 42, (5.90, 44.85)))
                       for ref in ({}, {"reference": "geographic"})],
    # Alpine relief (51 % mean slope on 30 m cells, 550–1940 m; the tile's steepest place clear
    # of the scenes above, voids filled) with the other renderer's kind of parcels and with the
    # simulator's default fields: like the other renderer's hidden Alpine scene, never tuned on
    "judged_alpine": [("dem", seed, (5.55, 44.725), dict(texture=texture, psf_px=0.0, noise_dn=2.0, **ref))
                      for seed, texture in ((46, "mottled"), (48, "fields"))
                      for ref in ({}, {"reference": "geographic"})],
    # eight scenes never looked at before their figures were taken (new seeds, new places of
    # the tile 0.1° or more from every scene above): the other renderer's kind of parcels on
    # steep relief (31–34 % mean slope; one ascending), its flat parcels on gentler relief
    # (14 %), the default fields, and JPEG at quality 90, each against both kinds of reference
    "judged_fresh": [(*scene_, {**options, **ref}) for *scene_, options in (
        ("dem", 71, (5.15, 44.85), dict(texture="mottled", psf_px=0.0, noise_dn=2.0)),
        ("dem", 72, (5.70, 44.15), dict(texture="mottled", psf_px=0.0, noise_dn=2.0)),
        ("dem", 73, (5.45, 44.40), {}),
        ("dem", 74, (5.10, 44.30), dict(texture="parcels", psf_px=0.0, noise_dn=2.0)),
        ("dem", 75, (5.70, 44.15), dict(jpeg_quality=90)),
        ("dem", 76, (5.45, 44.40), dict(texture="mottled", psf_px=0.0, noise_dn=2.0, ascending=True)),
        ("smooth", 77, None, dict(texture="mottled", psf_px=0.0, noise_dn=2.0)),
        ("fractal", 78, None, dict(texture="mottled", psf_px=0.0, noise_dn=2.0)))
        for ref in ({}, {"reference": "geographic"})],
    # five more places never looked at (0.1° or more from every scene above), the other
    # renderer's kind of parcels, both references: drawn after the relief the reference shows
    # moved matches back, to judge that once
    "judged_fresh2": [("dem", seed, centre, dict(texture="mottled", psf_px=0.0, noise_dn=2.0, **ref))
                      for seed, centre in ((81, (5.22, 44.10)), (82, (5.60, 44.90)), (83, (5.85, 44.25)),
                                           (84, (5.75, 44.56)), (85, (5.10, 44.62)))
                      for ref in ({}, {"reference": "geographic"})],
    # five more places never looked at (0.1° or more from every scene above; one ascending),
    # the other renderer's kind of parcels, both references: drawn after the rays' test took the
    # model's σ at the point and the low-passed fit's shift kept its own σ, to judge those once
    "judged_fresh3": [("dem", seed, centre, dict(texture="mottled", psf_px=0.0, noise_dn=2.0, **extra, **ref))
                      for seed, centre, extra in ((91, (5.90, 44.45), {}), (92, (5.30, 44.80), {}),
                                                  (93, (5.55, 44.30), {"ascending": True}),
                                                  (94, (5.10, 44.45), {}), (95, (5.42, 44.92), {}))
                      for ref in ({}, {"reference": "geographic"})],
    # three more places never looked at (0.1° or more from every scene above and from the
    # orientation sweeps'), the other renderer's kind of parcels, both references: to judge at
    # 15 km (--size 6000) once, after the bend's limit became a curvature and a bend that does
    # not settle left no match
    "judged_fresh4": [("dem", seed, centre, dict(texture="mottled", psf_px=0.0, noise_dn=2.0, **ref))
                      for seed, centre in ((101, (5.18, 44.82)), (102, (5.84, 44.12)), (103, (5.45, 44.11)))
                      for ref in ({}, {"reference": "geographic"})],
    # four more places never looked at (0.1° or more from every scene above and from the
    # orientation sweeps'), the other renderer's kind of parcels, both references: drawn after
    # the orientation's default target became one pixel, to judge the transfer once as it
    # stands — two at 10 km (the default size), two at 15 km (--size 6000)
    "judged_fresh5": [("dem", seed, centre, dict(texture="mottled", psf_px=0.0, noise_dn=2.0, **ref))
                      for seed, centre in ((111, (5.64, 44.58)), (112, (5.32, 44.50)))
                      for ref in ({}, {"reference": "geographic"})],
    "judged_fresh6": [("dem", seed, centre, dict(texture="mottled", psf_px=0.0, noise_dn=2.0, **ref))
                      for seed, centre in ((113, (5.20, 44.42)), (114, (5.68, 44.30)))
                      for ref in ({}, {"reference": "geographic"})],
    # JPEG block noise (8 × 8, as compressed PRISM products carry) on the other renderer's kind
    # of parcels: on smooth hills and on steep relief at two qualities (found on these; a gap)
    "jpeg_mottled": [("smooth", 54, None, dict(texture="mottled", psf_px=0.0, noise_dn=2.0, jpeg_quality=75)),
                     ("dem", 51, (5.35, 44.62), dict(texture="mottled", psf_px=0.0, noise_dn=2.0, jpeg_quality=75)),
                     ("dem", 51, (5.35, 44.62), dict(texture="mottled", psf_px=0.0, noise_dn=2.0, jpeg_quality=90))],
}
