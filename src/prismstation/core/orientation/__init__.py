"""Orientation without GCPs from a reference DEM, its pure parts: where F and B are relative
to N (:mod:`.view_offsets`), the relative DEMs and the control they give (:mod:`.dem_orient`),
the one adjustment of the shift field (:mod:`.field_adjust`, :mod:`.field_stats`), its tests
(:mod:`.consistency`, :mod:`.shift_field`) and what the terrain can fix (:mod:`.conditioning`)."""
