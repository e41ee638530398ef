"""Exact plane geometry on rationals: the brute-force references of the line-of-sight tests
(tests/test_occlusion.py, tests/test_placement_occlusion.py).  Points are pairs of
``fractions.Fraction``; :func:`q` makes one from floats, exactly."""

from __future__ import annotations

from fractions import Fraction


def q(p):
    """The point (x, y) of floats as exact rationals."""
    return (Fraction(float(p[0])), Fraction(float(p[1])))


def orient(a, b, c):
    """Twice the signed area of a, b, c: > 0 counter-clockwise, 0 collinear."""
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def on_segment(a, b, p):
    """p lies on the closed segment a–b."""
    return (orient(a, b, p) == 0 and min(a[0], b[0]) <= p[0] <= max(a[0], b[0])
            and min(a[1], b[1]) <= p[1] <= max(a[1], b[1]))


def segments_meet(p1, p2, q1, q2):
    """The closed segments p1–p2 and q1–q2 share a point (touching and collinear overlaps included)."""
    d1, d2 = orient(q1, q2, p1), orient(q1, q2, p2)
    d3, d4 = orient(p1, p2, q1), orient(p1, p2, q2)
    if ((d1 > 0 and d2 < 0) or (d1 < 0 and d2 > 0)) and ((d3 > 0 and d4 < 0) or (d3 < 0 and d4 > 0)):
        return True
    return on_segment(q1, q2, p1) or on_segment(q1, q2, p2) or on_segment(p1, p2, q1) or on_segment(p1, p2, q2)


def in_polygon(poly, p):
    """p inside the simple polygon or on its boundary (crossing number)."""
    n = len(poly)
    if any(on_segment(poly[i], poly[(i + 1) % n], p) for i in range(n)):
        return True
    inside = False
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        if (a[1] > p[1]) != (b[1] > p[1]):
            x = a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
            if x > p[0]:
                inside = not inside
    return inside


def in_disc(o, r, p):
    """p inside the closed disc of centre o and radius r."""
    return (p[0] - o[0]) ** 2 + (p[1] - o[1]) ** 2 <= r * r


def disc_meets_segment(o, r, a, b):
    """The closed disc (o, r) and the closed segment a–b share a point."""
    ab = (b[0] - a[0], b[1] - a[1])
    ao = (o[0] - a[0], o[1] - a[1])
    dot, l2 = ao[0] * ab[0] + ao[1] * ab[1], ab[0] ** 2 + ab[1] ** 2
    if l2 == 0 or dot <= 0:
        return in_disc(o, r, a)
    if dot >= l2:
        return in_disc(o, r, b)
    cr = ao[0] * ab[1] - ao[1] * ab[0]
    return cr * cr <= r * r * l2
