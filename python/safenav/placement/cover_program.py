"""The integer program behind :func:`safenav.placement.place_optimal`: one
coverage row per point of the route where the number of landmarks in view can
change, solved with ``scipy.optimize.milp`` (HiGHS).

Rows come from the core's visibility intervals [Placement Lemma 2] of each
edge (and, with corners, of each in-place turn); between consecutive interval
endpoints and alignment points coverage is constant, so one probe at every
such point and one in every gap make the program exact (the route is not
sampled).  Candidates on one bearing at a probe form a group ``g`` counted
once through ``z_g <= sum_{l in g} x_l``, ``0 <= z_g <= 1``.
"""

from __future__ import annotations

import math

import numpy as np

EPS = 1e-9           # [m] or [rad], the same rounding slack as the C++ core
BEARING_TOL = 1e-9   # [rad], bearings closer than this are one bearing


def bearing_groups(bearings: np.ndarray) -> list[np.ndarray]:
    """Indices of ``bearings`` [rad, in (−π, π]] grouped where consecutive
    sorted values differ by <= the bearing tolerance, across ±π too (as the
    core's distinct-bearing count)."""
    if bearings.size == 0:
        return []
    order = np.argsort(bearings, kind="stable")
    groups = np.split(order, np.flatnonzero(np.diff(bearings[order]) > BEARING_TOL) + 1)
    if len(groups) > 1 and bearings[order[0]] + 2 * math.pi - bearings[order[-1]] <= BEARING_TOL:
        groups = [np.concatenate([groups[-1], groups[0]])] + groups[1:-1]
    return groups


def _probes(pts: np.ndarray) -> tuple[np.ndarray, list]:
    """The probes: each point of ``pts`` (sorted) and each gap's midpoint,
    with the stretch ``(lo, hi)`` that each stands for."""
    n = len(pts)
    probe = np.concatenate([pts, 0.5 * (pts[:-1] + pts[1:])])
    return probe, [(t, t) if pi < n else (pts[pi - n], pts[pi - n + 1]) for pi, t in enumerate(probe)]


class CoverProgram:
    """Columns ``x_l`` (one per candidate met, in the order met) and ``z_g``
    (one per bearing group), and the coverage rows ``>= k`` (``>= `` the
    number of bearings in view where fewer than ``k`` are: those stretches
    are kept in :attr:`uncovered`)."""

    def __init__(self, k: int, distinct_bearings: bool):
        self.k = k
        self.distinct_bearings = distinct_bearings
        self.col_of: dict[int, int] = {}
        self.z_groups: dict[tuple, int] = {}
        self.rows: list[tuple[list, int]] = []   # (columns, required)
        self._seen: set = set()
        self.uncovered: list = []

    def _col(self, i) -> int:
        return self.col_of.setdefault(int(i), len(self.col_of))

    def add_row(self, groups: list[np.ndarray], where: str, idx: int, a: float, b: float) -> None:
        cols = []
        for g in groups:
            members = [self._col(i) for i in g]  # every candidate gets its own x, grouped or not
            if len(g) == 1:
                cols.append(("x", members[0]))
            else:
                key = tuple(sorted(int(i) for i in g))
                cols.append(("z", self.z_groups.setdefault(key, len(self.z_groups))))
        need = self.k
        if len(cols) < self.k:
            self.uncovered.append((where, idx, a, b))
            need = len(cols)
        if need == 0:
            return
        key = (tuple(sorted(cols)), need)
        if key not in self._seen:
            self._seen.add(key)
            self.rows.append((cols, need))

    def add_edge(self, e: int, length: float, vis, mask, align_t, occluded: bool) -> None:
        """The rows of edge ``e`` from its intervals ``vis[mask]`` (an
        ``EdgeVisibility``) and the alignment points ``align_t`` along it."""
        a, b, x, y, ci = vis.start[mask], vis.end[mask], vis.x[mask], vis.y[mask], vis.candidate[mask]
        pts = np.concatenate([a, b, [0.0, length]] + ([align_t] if align_t is not None else []))
        pts = np.unique(np.clip(pts, 0.0, length))
        probe, stretch = _probes(pts)
        inview = (a[None, :] - EPS <= probe[:, None]) & (probe[:, None] <= b[None, :] + EPS)
        for pi, (t, (lo, hi)) in enumerate(zip(probe, stretch)):
            idx = np.flatnonzero(inview[pi])
            if occluded and idx.size > 1:   # pieces of one candidate are disjoint; count it once all the same
                idx = idx[np.unique(ci[idx], return_index=True)[1]]
            if self.distinct_bearings and idx.size > 1:
                groups = [ci[idx[g]] for g in bearing_groups(np.arctan2(y[idx], x[idx] - t))]
            else:
                groups = [np.array([ci[i]]) for i in idx]
            self.add_row(groups, "edge", e, lo, hi)

    def add_corner(self, v: int, turned: float, cv, mask) -> None:
        """The rows of the in-place turn of ``turned`` rad at vertex ``v``
        from its intervals ``cv[mask]`` (a corner ``EdgeVisibility``)."""
        a, b, ci = cv.start[mask], cv.end[mask], cv.candidate[mask]
        brg = np.arctan2(cv.y[mask], cv.x[mask])
        rays = bearing_groups(brg) if self.distinct_bearings else [np.array([i]) for i in range(len(ci))]
        pts = np.unique(np.clip(np.concatenate([a, b, [0.0, turned]]), 0.0, turned))
        for s, (lo, hi) in zip(*_probes(pts)):
            groups = [ci[g] for g in rays if ((a[g] - EPS <= s) & (s <= b[g] + EPS)).any()]
            self.add_row(groups, "corner", v, lo, hi)

    def solve(self, time_limit: float) -> tuple[np.ndarray, bool]:
        """The chosen candidates (sorted) and whether HiGHS proved them optimal."""
        from scipy.optimize import Bounds, LinearConstraint, milp
        from scipy.sparse import coo_matrix

        nx, nz = len(self.col_of), len(self.z_groups)
        cand_of_col = np.empty(nx, dtype=int)
        for cand, j in self.col_of.items():
            cand_of_col[j] = cand
        ri, cj, vals, lb = [], [], [], []
        for row, (cols, need) in enumerate(self.rows):
            for kind, j in cols:
                ri.append(row)
                cj.append(j if kind == "x" else nx + j)
                vals.append(1.0)
            lb.append(need)
        nrow = len(self.rows)
        for key, j in self.z_groups.items():   # z_g - sum_{l in g} x_l <= 0
            ri += [nrow] * (1 + len(key))
            cj += [nx + j] + [self.col_of[cand] for cand in key]
            vals += [1.0] + [-1.0] * len(key)
            nrow += 1
        A = coo_matrix((vals, (ri, cj)), shape=(nrow, nx + nz)).tocsr()
        lo = np.concatenate([lb, np.full(nz, -np.inf)])
        hi = np.concatenate([np.full(len(self.rows), np.inf), np.zeros(nz)])
        cost = np.concatenate([np.ones(nx), np.zeros(nz)])
        integrality = np.concatenate([np.ones(nx), np.zeros(nz)])
        res = milp(cost, constraints=LinearConstraint(A, lo, hi), integrality=integrality, bounds=Bounds(0, 1),
                   options={"time_limit": float(time_limit), "presolve": True})
        if res.x is None:
            raise ValueError(f"the placement integer program found no solution ({res.message})")
        return np.sort(cand_of_col[res.x[:nx] > 0.5]), bool(res.status == 0)
