"""Storage the views of one render_views() call share: it shrinks only to what the largest view needs.

The methods whose storage grows on overflow (the A-buffer's node pool, paged_ll's pages,
multi-layer peeling's nodes) also shrink it to what the last frame needed. The views of one call
are drawn one after another into the same storage and need different amounts (a cube map's
floor against its sky): shrunk to one view's need, the pool would be made again for the next
view, every call. So a shrink is decided at a call's last view, from the largest need of its views.
"""

from __future__ import annotations


class ViewsNeed:
    """The largest need of the views of the call being drawn, known at its last view."""

    def __init__(self):
        self._largest = 0

    def __call__(self, frame, need: int) -> int | None:
        """`need` (this view's) joined with the earlier views' of its call: the largest at the call's last view,
        None before it (no shrink between views). A plain render() is a call of one view."""
        self._largest = need if frame.view_index == 0 else max(self._largest, need)
        return self._largest if frame.view_index == frame.view_count - 1 else None
