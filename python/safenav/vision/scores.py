"""Middlebury-style scores of a disparity map against ground truth, counted
two ways (:class:`DisparityScores`, :func:`disparity_scores`): the yardstick
of LanBLoc's SGBM ranging on real pairs (:mod:`safenav.experiments.real`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["DisparityScores", "disparity_scores", "MIDDLEBURY_THRESHOLDS"]


#: Middlebury 2014's error thresholds [px] (bad-0.5, bad-1, bad-2, bad-4).
MIDDLEBURY_THRESHOLDS = (0.5, 1.0, 2.0, 4.0)


@dataclass(frozen=True)
class DisparityScores:
    """Middlebury-style scores of a disparity map, counted two ways.

    With ``G`` the pixels that have a ground truth, ``M ⊆ G`` those the
    matcher gave a disparity and ``E_t ⊆ M`` those whose error
    ``|d − d_gt|`` exceeds ``t`` pixels:

    * ``bad_all[t]     = (|E_t| + |G − M|) / |G|`` — unmatched pixels count as
      bad (Middlebury's convention for the ranking);
    * ``bad_matched[t] = |E_t| / |M|`` — over matched pixels only, to be read
      with ``density = |M| / |G|``.
    """

    thresholds: tuple[float, ...]  #: t [px]
    bad_all: tuple[float, ...]     #: fraction of G that is unmatched or off by more than t
    bad_matched: tuple[float, ...]  #: fraction of M off by more than t
    density: float                 #: |M| / |G|
    mae: float                     #: mean |d − d_gt| over M [px]
    rmse: float                    #: RMS of d − d_gt over M [px]
    n_ground_truth: int            #: |G|
    n_matched: int                 #: |M|

    def bad(self, threshold: float, counting: str = "all") -> float:
        """The bad-``threshold`` fraction, ``counting`` = ``"all"`` or ``"matched"``."""
        if threshold not in self.thresholds:
            raise ValueError(f"threshold = {threshold!r} was not scored; scored: {self.thresholds}")
        if counting not in ("all", "matched"):
            raise ValueError(f"counting = {counting!r} must be 'all' or 'matched'")
        i = self.thresholds.index(threshold)
        return (self.bad_all if counting == "all" else self.bad_matched)[i]

    def as_dict(self) -> dict:
        """Flat columns: ``bad2_all``, ``bad2_matched``, … (``bad0.5_all`` for t = 0.5),
        ``density``, ``mae``, ``rmse``, ``n_ground_truth``, ``n_matched``."""
        out = {}
        for t, a, m in zip(self.thresholds, self.bad_all, self.bad_matched):
            out[f"bad{t:g}_all"] = a
            out[f"bad{t:g}_matched"] = m
        out.update(density=self.density, mae=self.mae, rmse=self.rmse, n_ground_truth=self.n_ground_truth,
                   n_matched=self.n_matched)
        return out


def disparity_scores(disparity, ground_truth, thresholds=MIDDLEBURY_THRESHOLDS) -> DisparityScores:
    """Score ``disparity`` (NaN where unmatched) against ``ground_truth``
    (NaN or ±inf where unknown), both ``(H, W)`` pixels; see
    :class:`DisparityScores`.  A ground truth with no known pixel raises
    ``ValueError``; with no matched pixel the matched-only scores are NaN."""
    d = np.asarray(disparity)
    g = np.asarray(ground_truth)
    for name, a in (("disparity", d), ("ground_truth", g)):
        if a.ndim != 2 or not np.issubdtype(a.dtype, np.floating):
            raise ValueError(f"{name} must be a 2-D float array, got shape {a.shape} dtype {a.dtype}")
    if d.shape != g.shape:
        raise ValueError(f"disparity and ground_truth differ in shape: {d.shape} vs {g.shape}")
    ts = tuple(float(t) for t in thresholds)
    if not ts or not all(math.isfinite(t) and t >= 0 for t in ts):
        raise ValueError(f"thresholds = {thresholds!r} must be finite numbers >= 0")
    if np.isinf(d).any():
        raise ValueError("disparity has infinite values; mark unmatched pixels NaN")
    known = np.isfinite(g)
    n_g = int(known.sum())
    if n_g == 0:
        raise ValueError("ground_truth has no known pixel (all NaN/inf)")
    matched = known & np.isfinite(d)
    n_m = int(matched.sum())
    err = np.abs(d[matched].astype(np.float64) - g[matched].astype(np.float64))
    n_bad = [int((err > t).sum()) for t in ts]
    nan = math.nan
    return DisparityScores(
        thresholds=ts,
        bad_all=tuple((b + n_g - n_m) / n_g for b in n_bad),
        bad_matched=tuple(b / n_m if n_m else nan for b in n_bad),
        density=n_m / n_g,
        mae=float(err.mean()) if n_m else nan,
        rmse=float(np.sqrt(np.mean(err ** 2))) if n_m else nan,
        n_ground_truth=n_g, n_matched=n_m)
