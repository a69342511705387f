"""File ▸ New project from product… (also under Tools): a JAXA PRISM level 1B2 product folder
(CEOS ``VOL-/LED-/IMG-/TRL-`` files with ``summary.txt``, or GeoTIFF ``IMG-*.tif``; a triplet
or one view) becomes a new, untitled project without a hand-written scene.

The scene.json is written from the product by :func:`prismstation.io.products.write_scene_for_product`
(see :meth:`ProjectFiles.new_project_from_product`); Save As then asks where the project goes
and writes the scene beside it. A folder that is not a product is a message naming what is
missing.
"""
from __future__ import annotations


def install(ctx) -> None:
    a = ctx.add_action("New project from &product…", lambda: ctx.files.new_project_from_product(),
                       tip="A new project on a JAXA PRISM 1B2 product folder (CEOS or GeoTIFF)")
    ctx.tools["product"] = a
    ctx.tools_menu.addAction(a)
    if ctx.file_menu is not None:
        ctx.file_menu.insertAction(ctx.open_action, a)
