"""Least squares and statistics every subject uses: weighted least squares with σ0 and
covariances (:mod:`.lsq`), the fitted-transform protocol (:mod:`.estimate`), 2-D affine
transforms (:mod:`.affine`), residual statistics and the NMAD (:mod:`.stats`)."""
