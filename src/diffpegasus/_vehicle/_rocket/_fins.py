"""A fin's planform by strips along its span: what Barrowman's method takes from it.

Every planform (trapezoidal, elliptical, free-form polygon) is described the same
way, by chordwise strips at span positions `y` (m from the root) with quadrature
weights `w` (m): each strip's leading edge `lead` (m behind the root's leading
edge), its chord `chord` (m) and the slope `d(mid-chord)/dy` of its mid-chord line.
One function, [`fin_constants`][], turns the strips into the fin set's normal-force
slope and centre of pressure:

- area `Af = int c dy`, span `s = int dy`, aspect ratio `AR = 2 s^2 / Af`;
- mid-chord sweep `G` by `cos G = (1/s) int cos(atan(d mid/dy)) dy`;
- centre of pressure at the quarter chord of the mean aerodynamic chord,
  `(1/Af) int (lead + c/4) c dy` behind the root's leading edge;
- per pair of fins `2 pi AR (Af/Aref) / (2 + sqrt(4 + (beta AR / cos G)^2))`
  (Diederich's planform correlation, compressibility by `beta`), times the number
  of pairs (`n/2`, with OpenRocket's and RocketPy's 2.37, 2.74, 2.99, 3.24 for
  5 to 8 fins, which shade each other) and the body interference `1 + R/(s + R)`.

For a trapezoid the integrals are Barrowman's closed forms (two Gauss points on the
span integrate them exactly): the centre of pressure `xr (cr + 2 ct) / (3 (cr +
ct)) + (cr + ct - cr ct / (cr + ct)) / 6`. For an ellipse, `0.2878 cr` (RocketPy
takes `0.288 cr`). A polygon's strips are exact between its corners' span positions
(edges straight there), so its area is the shoelace formula's.
"""

import numpy as np


_GAUSS2 = np.polynomial.legendre.leggauss(2)
_GAUSS_ELLIPSE = np.polynomial.legendre.leggauss(48)
_SHADING = {5: 2.37, 6: 2.74, 7: 2.99, 8: 3.24}  # n fins' pairs, after interference


def _on(a, b, nodes):
    """Gauss-Legendre `(points, weights)` on `[a, b]`."""
    x, w = nodes
    return a + (b - a) * (x + 1) / 2, w * (b - a) / 2


def trapezoid_strips(root, tip, span, sweep):
    """`(y, w, lead, chord, mid_slope)` of a trapezoid: root and tip chords, span and
    the leading edge's run `sweep` (all m) from root to tip."""
    y, w = _on(0.0, span, _GAUSS2)
    lead = sweep * y / span
    chord = root + (tip - root) * y / span
    slope = np.full_like(y, (sweep + tip / 2 - root / 2) / span)
    return y, w, lead, chord, slope


def ellipse_strips(root, span):
    """`(y, w, lead, chord, mid_slope)` of an elliptical fin (root chord and span m;
    the chord `root sqrt(1 - (y/span)^2)` centred on the root's mid-chord, as
    RocketPy's and OpenRocket's), integrated in `y = span sin t`."""
    t, wt = _on(0.0, np.pi / 2, _GAUSS_ELLIPSE)
    y, w = span * np.sin(t), wt * span * np.cos(t)
    chord = root * np.cos(t)
    return y, w, (root - chord) / 2, chord, np.zeros_like(y)


def polygon_strips(points):
    """`(y, w, lead, chord, mid_slope)` of a free-form fin: `points` `(k, 2)` m, the
    outline `(x, y)` in order (x aft from the root's leading edge, y out along the
    span), closed back to the first point. The span runs from the lowest to the
    highest point; at each `y` the chord is the length inside the outline, from
    the first crossing (the leading edge) to the last."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3 or not np.all(np.isfinite(p)):
        raise ValueError("needs at least three finite (x, y) points")
    if np.allclose(p[0], p[-1]):
        p = p[:-1]
    edges = np.stack([p, np.roll(p, -1, axis=0)], axis=1)  # (k, 2 ends, 2)
    levels = np.unique(p[:, 1])
    ys, ws, leads, chords, slopes = [], [], [], [], []
    for lo, hi in zip(levels[:-1], levels[1:], strict=True):
        y, w = _on(lo, hi, _GAUSS2)
        ends = []
        for yy in (lo, hi, *y):
            ends.append(_crossings(edges, yy, lo, hi))
        (l0, t0, _), (l1, t1, _) = ends[0], ends[1]
        slope = ((l1 + t1) - (l0 + t0)) / 2 / (hi - lo)
        for (lead, _, inside), yy, ww in zip(ends[2:], y, w, strict=True):
            ys.append(yy)
            ws.append(ww)
            leads.append(lead)
            chords.append(inside)
            slopes.append(slope)
    if not ys:
        raise ValueError("the points have no extent along the span")
    return tuple(np.asarray(a) for a in (ys, ws, leads, chords, slopes))


def _crossings(edges, y, lo, hi):
    """`(lead, trail, length inside)` of the outline's crossings at `y`, taken with
    the edges that span the band `[lo, hi]` (so the band's ends see the same edges
    as its inside)."""
    y0, y1 = edges[:, 0, 1], edges[:, 1, 1]
    spans = np.minimum(y0, y1) <= lo
    spans &= np.maximum(y0, y1) >= hi
    spans &= y0 != y1
    e = edges[spans]
    f = (y - e[:, 0, 1]) / (e[:, 1, 1] - e[:, 0, 1])
    x = np.sort(e[:, 0, 0] + f * (e[:, 1, 0] - e[:, 0, 0]))
    if len(x) < 2:
        return 0.0, 0.0, 0.0
    inside = float(np.sum(x[1::2] - x[0::2])) if len(x) % 2 == 0 else x[-1] - x[0]
    return float(x[0]), float(x[-1]), inside


def fin_constants(strips, n, body_radius, ref_radius):
    """`(a, b, cp)` of `n` fins of one planform `strips` (see the module):
    `CN_alpha(beta) = a / (2 + sqrt(4 + (beta b)^2))` per radian on the reference
    area `pi ref_radius^2` (interference with a body of radius `body_radius` m
    included) and `cp` m behind the root's leading edge."""
    y, w, lead, chord, slope = strips
    area = float(np.sum(w * chord))
    # relative to the fin's bounding box: a flat outline leaves rounding's area
    box = float(np.sum(w)) * float(np.max(lead + chord) - np.min(lead))
    if not area > 1e-9 * box:
        raise ValueError(f"the fin has no area ({area:g} m^2)")
    span = float(np.sum(w))
    aspect = 2 * span**2 / area
    cos_g = float(np.sum(w / np.hypot(1.0, slope))) / span
    cp = float(np.sum(w * chord * (lead + chord / 4))) / area
    pairs = _SHADING.get(int(n), n / 2)
    interference = 1 + body_radius / (span + body_radius)
    a = 2 * np.pi * aspect * area / (np.pi * ref_radius**2) * pairs * interference
    return a, aspect / cos_g, cp
