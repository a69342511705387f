"""JPEG block-noise reduction for display (Tadono et al. 2008, §3), switchable per view.

Tools ▸ JPEG block-noise reduction has one checkable action per view; a checked view shows its
overview and tiles through :func:`prismstation.core.matching.deblock.deblock` (8 × 8 blocks, applied to
each displayed array as it is shown). The choice is kept per view name across project reloads.
"""
from __future__ import annotations

from prismstation.core.matching.deblock import deblock
from prismstation.errors import ModelError


def deblock_display(arr):
    """Display filter: :func:`deblock` for 2-D arrays large enough, others unchanged."""
    if getattr(arr, "ndim", 0) != 2 or min(arr.shape) < 8:
        return arr
    try:
        return deblock(arr)
    except ModelError:
        return arr


class DeblockTool:
    def __init__(self, ctx):
        self.ctx = ctx
        self.on: set[str] = set()
        self.menu = ctx.tools_menu.addMenu("JPEG block-noise reduction")
        self.actions: dict = {}
        ctx.views.images_loaded.connect(self._rebuild)

    def _rebuild(self) -> None:
        self.menu.clear()
        self.actions = {}
        for name, iv in self.ctx.views.views.items():
            a = self.menu.addAction(f"View {name}")
            a.setCheckable(True)
            a.setChecked(name in self.on)
            a.toggled.connect(lambda on, n=name: self.set_enabled(n, on))
            self.actions[name] = a
            if name in self.on and iv.display_filter is None:
                iv.set_display_filter(deblock_display)

    def set_enabled(self, view: str, on: bool) -> None:
        """Show ``view`` deblocked (``on``) or as read."""
        (self.on.add if on else self.on.discard)(view)
        iv = self.ctx.views.views.get(view)
        if iv is not None:
            iv.set_display_filter(deblock_display if on else None)
        a = self.actions.get(view)
        if a is not None and a.isChecked() != on:
            a.setChecked(on)


def install(ctx) -> None:
    ctx.tools["deblock"] = DeblockTool(ctx)
