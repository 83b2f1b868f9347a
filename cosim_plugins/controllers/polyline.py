"""A reference polyline's segments and arc lengths: the closest point by projection, the point at an arc length.

Both are continuous in their argument (a position, an arc length): the
closest point is the projection onto the nearest segment, not the nearest
vertex, and a point at an arc length is interpolated along its segment, so a
micrometre's move of the position moves them by about a micrometre, never by
a path spacing. What is left is inherent to projecting onto a polyline: on
the inner side of a vertex where the path bends by theta, a position d from
the path that crosses the bend's bisector moves its projection from one
segment to the next, d theta further on (0.5 mm inside the racetrack's 40 mm
curves, sampled every 0.5 mm: 6 um); and a position equally far from two
separate stretches of the path (a circle's centre) has two closest points.

Segment ``j`` runs from vertex ``j`` to vertex ``j + 1`` (a closed path's last
one back to vertex 0). The search for the closest point runs over a window
of segments (:meth:`Polyline.window`), built on a copy of the coordinates
extended by the window's reach on both sides, so a closed path's window
across its start is a slice like any other.
"""

from __future__ import annotations

import bisect
import functools
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Polyline:
    """The geometry of one polyline, computed once (see :func:`polyline`); ``m`` segments."""

    closed: bool
    #: segment starts (m, 3) [m] and their vectors to the segment ends (m, 3) [m]
    starts: np.ndarray
    vectors: np.ndarray
    #: segment lengths (m,) [m]
    lengths: np.ndarray
    #: the last vertex (3,) [m]
    end: np.ndarray
    #: arc length at each segment start, and the total last (m + 1,) [m]
    arcs: np.ndarray
    #: the search arrays, k vertices and k - 1 segments between them: vertex rows (k, 3) [m],
    #: half their squared norms (k,) [m^2], each segment's half squared length (k - 1,) [m^2]
    #: and inverse squared length (k - 1,) [1/m^2] (0 for an empty segment)
    ext_rows: np.ndarray
    ext_half_sq: np.ndarray
    ext_half_len2: np.ndarray
    ext_inv_len2: np.ndarray
    #: the path segment of the search arrays' segment 0, as an offset (closed: -back)
    ext_offset: int
    #: the window's reach [segments] behind and ahead of the last closest segment
    back: int
    ahead: int

    @property
    def segments(self) -> int:
        return len(self.lengths)

    @property
    def length_m(self) -> float:
        return float(self.arcs[-1])

    def window(self, last: int | None) -> tuple[int, int]:
        """The search arrays' segments ``[lo, hi)`` to search: all the path's segments when
        ``last`` is None, else ``back`` behind to ``ahead`` beyond the path segment ``last``
        (clipped at an open path's ends)."""
        m = self.segments
        if self.closed:
            lo = self.back if last is None else last
            return lo, lo + (m if last is None else self.back + self.ahead)
        if last is None:
            return 0, m
        return max(last - self.back, 0), min(last + self.ahead, m)

    def closest(self, position_m: np.ndarray, last: int | None) -> tuple[int, float]:
        """``(segment, fraction)``: the point of the window's segments (see :meth:`window`)
        closest to ``position_m`` (3,) [m], at ``fraction`` in [0, 1] along path segment ``segment``.

        With ``h_i = (|v_i|^2 - 2 v_i . p) / 2`` for each vertex ``v_i`` (one matrix-vector
        product; ``h_i + |p|^2 / 2`` is half its squared distance to ``p``), a segment's
        ``(p - v_i) . (v_i+1 - v_i) = h_i - h_i+1 + l2 / 2`` (``l2`` its squared length), the
        projection's fraction ``t`` is that over ``l2``, clipped to [0, 1], and
        ``h_i - t ((p - v_i) . (v_i+1 - v_i) - t l2 / 2)`` is half its squared distance less
        ``|p|^2 / 2``: arithmetic on rows of the window's length, no (w, 3) array."""
        lo, hi = self.window(last)
        h = self.ext_half_sq[lo:hi + 1] - self.ext_rows[lo:hi + 1] @ position_m  # (w + 1,)
        c = h[:-1] - h[1:]
        l2 = self.ext_half_len2[lo:hi]
        c += l2  # (p - start) . vector, (w,) [m^2]
        t = c * self.ext_inv_len2[lo:hi]
        np.maximum(t, 0.0, out=t)
        np.minimum(t, 1.0, out=t)
        l2 = l2 * t
        np.subtract(c, l2, out=c)
        c *= t
        np.subtract(h[:-1], c, out=c)  # (squared distance - |p|^2) / 2, (w,) [m^2]
        k = int(c.argmin())
        return (lo + k + self.ext_offset) % self.segments, float(t[k])

    @functools.cached_property
    def _rows(self) -> tuple[list, list, list]:
        """Per segment as Python floats, for the scalar lookups every tick: (start x, y, z, vector
        x, y, z) rows, the lengths [m], and ``arcs`` [m]."""
        return np.hstack([self.starts, self.vectors]).tolist(), self.lengths.tolist(), self.arcs.tolist()

    def point(self, segment: int, fraction: float) -> np.ndarray:
        """The point (3,) [m] at ``fraction`` along ``segment``."""
        x, y, z, u, v, w = self._rows[0][segment]
        return np.array((x + fraction * u, y + fraction * v, z + fraction * w))

    def arc(self, segment: int, fraction: float) -> float:
        """The arc length [m] from vertex 0 to the point at ``fraction`` along ``segment``."""
        _, lengths, arcs = self._rows
        return arcs[segment] + fraction * lengths[segment]

    def at_arc(self, s_m: float) -> tuple[np.ndarray, bool]:
        """``(point (3,) [m], past_end)``: the point at arc length ``s_m`` [m] from vertex 0
        (a closed path wraps; an open one stops at its last vertex, ``past_end`` True there)."""
        _, lengths, arcs = self._rows
        total = arcs[-1]
        if self.closed:
            s_m %= total
        elif s_m >= total:
            return self.end.copy(), True
        elif s_m <= 0.0:
            return self.starts[0].copy(), False
        j = min(bisect.bisect_right(arcs, s_m) - 1, len(lengths) - 1)
        size = lengths[j]
        return self.point(j, (s_m - arcs[j]) / size if size > 0 else 0.0), False

    def at_arcs(self, s_m: np.ndarray) -> np.ndarray:
        """The points (k, 3) [m] at arc lengths ``s_m`` (k,) [m], as :meth:`at_arc` does one."""
        arcs = self.arcs
        s_m = np.asarray(s_m, dtype=float)
        s_m = s_m % arcs[-1] if self.closed else np.clip(s_m, 0.0, arcs[-1])
        j = np.clip(np.searchsorted(arcs, s_m, side="right") - 1, 0, self.segments - 1)
        size = self.lengths[j]
        frac = np.divide(s_m - arcs[j], size, out=np.zeros_like(s_m), where=size > 0)
        points = self.starts[j] + frac[:, None] * self.vectors[j]
        if not self.closed:
            points[s_m >= arcs[-1]] = self.end
        return points


@functools.lru_cache(maxsize=16)
def _wrapped(n: int, back: int, ahead: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed path's search vertices ``-back .. n + ahead - 1`` (mod n) and their segments (all
    but the last), as indices into its n vertices (the same every time the path moves)."""
    vertex = np.arange(-back, n + ahead) % n
    vertex.flags.writeable = False
    return vertex, vertex[:-1]


def polyline(points_m: np.ndarray, closed: bool, back: int, ahead: int) -> Polyline:
    """The :class:`Polyline` of ``points_m`` (n, 3) [m] (``closed``: the last point joins the
    first), searched ``back`` segments behind and ``ahead`` beyond the last closest one."""
    pts = np.asarray(points_m, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2:
        raise ValueError(f"a reference polyline is (n >= 2, 3) points, got shape {pts.shape}")
    if back < 0 or ahead < 1:
        raise ValueError(f"the search window reaches back >= 0 and ahead >= 1 segments, got {back}, {ahead}")
    vertices = np.concatenate([pts, pts[:1]]) if closed else pts
    starts = vertices[:-1]
    vectors = vertices[1:] - starts
    len2 = np.einsum("ij,ij->i", vectors, vectors)
    lengths = np.sqrt(len2)
    arcs = np.zeros(len(lengths) + 1)
    np.cumsum(lengths, out=arcs[1:])
    inv = np.divide(1.0, len2, out=np.zeros_like(len2), where=len2 > 0)
    half_sq = 0.5 * np.einsum("ij,ij->i", pts, pts)
    if closed:  # vertices -back .. n + ahead - 1 (mod n): a window from any segment is a slice
        vertex, seg = _wrapped(len(pts), back, ahead)
        rows, sq, offset = pts.take(vertex, axis=0), half_sq.take(vertex), -back
        len2, inv = len2.take(seg), inv.take(seg)
    else:
        rows, sq, offset = np.ascontiguousarray(pts), half_sq, 0
    return Polyline(closed=closed, starts=starts, vectors=vectors, lengths=lengths, end=pts[-1].copy(), arcs=arcs,
                    ext_rows=rows, ext_half_sq=sq, ext_half_len2=0.5 * len2, ext_inv_len2=inv, ext_offset=offset,
                    back=back, ahead=ahead)
