"""The calls of the public-API fuzz test (``test_fuzz.py``): ``Draw``, the
argument generator of one call (valid values most of the time, hostile ones
otherwise), and ``TARGETS``, one function per API area that draws its
arguments and makes the call."""

from __future__ import annotations

import math

import numpy as np

#: The exceptions a call may raise (with a short message); anything else fails the call.
ALLOWED = (ValueError, TypeError, IndexError, KeyError, RuntimeError, OverflowError)

HOSTILE = [math.nan, math.inf, -math.inf, 1e308, -1e308, 1e-310, -1e-310, 0.0, -1.0, 1e154, 5e-324,
           None, "1", True, [], 2**70]


class Draw:
    """Argument generator for one call; records what it drew, for the report."""

    def __init__(self, seed: int, i: int, hostility: float = 0.15):
        self.rng = np.random.default_rng([seed, i])
        self.p = hostility
        self.log: list[str] = []

    def _note(self, v):
        r = repr(v) if not isinstance(v, np.ndarray) else f"array{v.shape}:{np.array2string(v.ravel()[:6], precision=3)}"
        self.log.append(r[:120])
        return v

    def hostile(self) -> bool:
        return self.rng.random() < self.p

    def _pick(self, seq):
        return seq[int(self.rng.integers(len(seq)))]

    # -- scalars -----------------------------------------------------------
    def num(self, lo=-10.0, hi=10.0):
        if self.hostile():
            return self._note(self._pick(HOSTILE))
        return self._note(float(self.rng.uniform(lo, hi)))

    def pos(self, lo=1e-3, hi=10.0):
        if self.hostile():
            return self._note(self._pick(HOSTILE))
        return self._note(float(np.exp(self.rng.uniform(np.log(lo), np.log(hi)))))

    def prob(self):
        return self.num(0.0, 1.0)

    def count(self, lo=1, hi=20):
        if self.hostile():
            return self._note(self._pick([0, -1, 1.5, None, True, 2**31, 2**63, "3", math.nan]))
        return self._note(int(self.rng.integers(lo, hi + 1)))

    # -- arrays ------------------------------------------------------------
    def arr(self, shape, scale=10.0, positive=False):
        """A float array of ``shape`` (``None`` entries: a random size 0..40)."""
        shp = tuple(int(self.rng.integers(1, 41)) if s is None else s for s in shape)
        a = self.rng.uniform(0.0 if positive else -scale, scale, shp)
        if self.hostile():
            kind = int(self.rng.integers(8))
            if kind == 0 and a.size:
                a.flat[int(self.rng.integers(a.size))] = self._pick([math.nan, math.inf, -math.inf, 1e308, -1e308])
            elif kind == 1:
                a = a * self._pick([1e308, 1e300, 1e-310, 1e154, -1e308])
            elif kind == 2:
                a = np.zeros((0,) + shp[1:])
            elif kind == 3:
                a = self.rng.uniform(-scale, scale, tuple(int(self.rng.integers(0, 5)) for _ in range(int(self.rng.integers(0, 4)))))
            elif kind == 4:
                a = self._pick([None, "abc", [["a", "b"]], 3.0, [[1.0, 2.0], [3.0]]])
            elif kind == 5:
                a = np.zeros(shp)
            elif kind == 6:
                a = np.full(shp, self._pick([1e308, -1e308, 1e-310, 5e-324]))
            else:
                a = a.astype(self._pick([np.int64, np.float32, np.complex128, object]))
        return self._note(a)

    def points(self, n=None, scale=20.0):
        return self.arr((n, 2), scale)

    def path(self):
        """A polyline, mostly well formed: a random walk."""
        if self.hostile():
            return self.points()
        n = int(self.rng.integers(2, 60))
        steps = self.rng.normal(0.0, 3.0, (n - 1, 2)) + [2.0, 0.0]
        return self._note(np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)]))

    def state(self):
        x = self.arr((4,), 10.0)
        if isinstance(x, np.ndarray) and x.shape == (4,) and x.dtype == np.float64:
            x[2] = abs(x[2]) / 3.0
        return x

    def control(self):
        return self.arr((2,), 2.0)

    def cov(self, n):
        if self.hostile():
            kind = int(self.rng.integers(6))
            if kind == 0:
                return self._note(np.eye(n) * self._pick([1e308, 1e300, 1e-310, 0.0, -1.0, 1e154]))
            if kind == 1:
                return self._note(self.rng.uniform(-1, 1, (n, n)))
            return self.arr((n, n))
        A = self.rng.normal(0.0, 1.0, (n, n))
        return self._note(A @ A.T * self.rng.uniform(1e-4, 1.0) + np.eye(n) * 1e-3)

    def params(self):
        from safenav import BmmParams

        kw = {}
        for name in ("acceleration", "deceleration", "max_speed", "max_heading_rate", "dt", "terrain_effect",
                     "speed_noise", "heading_noise", "position_noise"):
            if self.rng.random() < 0.15:
                kw[name] = self.pos(1e-2, 5.0) if self.rng.random() < 0.5 else self._note(self._pick(HOSTILE))
        return BmmParams(**kw)

    def zones(self):
        from safenav import RiskZones

        if self.rng.random() < 0.5:
            return None
        return RiskZones(half_width=self.pos(0.1, 5.0),
                         weights=[self.pos(0.1, 10.0) for _ in range(int(self.rng.integers(0, 6)))])


# ---------------------------------------------------------------------------
# The calls
# ---------------------------------------------------------------------------

def _model(d: Draw):
    from safenav import MeasurementModel

    kind = int(d.rng.integers(5))
    if kind == 0:
        return MeasurementModel.position(d.cov(2) if d.rng.random() < 0.7 else None)
    if kind == 1:
        return MeasurementModel.speed_heading(d.cov(2))
    lm = d.points(scale=30.0)
    if kind == 2:
        return MeasurementModel.range(lm, d.pos())
    if kind == 3:
        return MeasurementModel.bearing(lm, d.pos(1e-3, 1.0))
    return MeasurementModel.range_bearing(lm, d.pos(), d.pos(1e-3, 1.0))


def _measurement(d: Draw):
    model = _model(d)
    op = int(d.rng.integers(4))
    if op == 0:
        return model.predict(d.state())
    if op == 1:
        return model.jacobian(d.state())
    if op == 2:
        return model.residual(d.arr((model.dim,)), d.arr((model.dim,)))
    return model.R if model.dim <= 400 else model.dim


def _filter(d: Draw):
    from safenav import Ekf, InformationFilter, ParticleFilter

    kind = int(d.rng.integers(3))
    params, x0, P0 = d.params(), d.state(), d.cov(4)
    if kind == 0:
        f = Ekf(params, x0, P0, gate=d.prob() if d.rng.random() < 0.3 else 0.0)
    elif kind == 1:
        f = ParticleFilter(params, x0, P0, n_particles=d.count(1, 300), seed=d.count(0, 99))
    else:
        f = InformationFilter(params, x0, P0)
    out = []
    for _ in range(int(d.rng.integers(1, 6))):
        if d.rng.random() < 0.5:
            f.predict(d.control())
        else:
            model = _model(d)
            truth = np.asarray(f.x, dtype=float) + d.rng.normal(0.0, 0.1, 4)
            z = model.predict(truth) if d.rng.random() < 0.7 else d.arr((model.dim,))
            out.append(f.update(model, z))
    return f.x, f.P, out


def _filter_trajectory(d: Draw):
    from safenav import filter_trajectory

    n = int(d.rng.integers(1, 30))
    controls = d.arr((n, 2), 2.0)
    kw = {}
    if d.rng.random() < 0.7:
        kw["position"] = d.arr((n, 2), 20.0)
    if d.rng.random() < 0.3:
        lm = d.points(5)
        kw.update(landmarks=lm, ranges=d.arr((n, 5), 20.0, positive=True), range_std=d.pos())
    return filter_trajectory(controls, d.state(), d.cov(4), params=d.params(),
                             filter=d._pick(["ekf", "pf", "eif", "ukf"]), n_particles=d.count(1, 200), **kw)


def _bmm(d: Draw):
    from safenav import Bmm

    bmm = Bmm(d.params())
    op = d._pick(["predict", "jacobian", "noise_jacobian", "process_cov", "transition", "simulate", "next_speed",
                  "clipped_heading_change"])
    if op == "transition":
        return bmm.transition(d.state(), d.control(), d.arr((4,), 0.1))
    if op == "simulate":
        return bmm.simulate(d.state(), d.arr((None, 2), 2.0), seed=d.count(0, 99))
    if op == "next_speed":
        return bmm.next_speed(d.num(0, 5), d.num(0, 5))
    if op == "clipped_heading_change":
        return bmm.clipped_heading_change(d.num(-3, 3))
    return getattr(bmm, op)(d.state(), d.control())


def _wrap_angle(d: Draw):
    from safenav import wrap_angle

    return wrap_angle(d.num(-100, 100) if d.rng.random() < 0.5 else d.arr((None,), 100.0))


def _metrics(d: Draw):
    from safenav import metrics

    op = d._pick(["ade", "fde", "path_length", "path_length_error_percent", "distance_to_path", "wrs",
                  "wrs_of_deviation", "awrs", "nees", "chi2_interval", "evaluate"])
    if op == "ade":
        n = int(d.rng.integers(1, 30))
        return metrics.ade(d.points(n), d.points(n))
    if op in ("fde", "path_length_error_percent", "evaluate"):
        n = int(d.rng.integers(1, 30))
        return getattr(metrics, op)(d.points(n), d.path())
    if op == "path_length":
        return metrics.path_length(d.path())
    if op == "distance_to_path":
        return metrics.distance_to_path(d.points(), d.path())
    if op in ("wrs", "awrs"):
        return getattr(metrics, op)(d.points(), d.path(), d.zones())
    if op == "wrs_of_deviation":
        return metrics.wrs_of_deviation(d.arr((None,), 5.0), d.zones())
    if op == "nees":
        n = int(d.rng.integers(1, 10))
        covs = np.stack([d.cov(4) for _ in range(n)]) if d.rng.random() < 0.9 else d.arr((n, 4, 4))
        return metrics.nees(d.arr((n, 4)), d.arr((n, 4)), covs)
    return metrics.chi2_interval(d.count(1, 50), d.count(1, 1000), d.prob())


def _corridor(d: Draw):
    from safenav import Corridor

    c = Corridor(d.path(), d.zones(), half_width=d.pos(0.1, 5.0) if d.rng.random() < 0.3 else None)
    op = d._pick(["project", "point_at", "tangent_at", "distance", "arc_length", "signed_offset", "side", "zone",
                  "contains", "wrs", "awrs", "points_at"])
    if op == "project":
        return c.project(d.arr((2,), 50.0))
    if op in ("point_at", "tangent_at"):
        return getattr(c, op)(d.num(-10, 200))
    if op == "points_at":
        return c.points_at(d.arr((None,), 200.0))
    return getattr(c, op)(d.points(scale=50.0))


def _segments(d: Draw):
    from safenav import Bmm, Corridor
    from safenav import navigation

    c = Corridor(d.path(), d.zones())
    if d.rng.random() < 0.5:
        seg = c.segments(count=d.count(1, 30), spacing=d.pos(0.05, 5.0), sub_segments=d.count(1, 6),
                         disc_sides=d.count(3, 24))
    else:
        seg = c.segments(length=d.pos(0.5, 50.0), sub_segments=d.count(1, 6))
    op = d._pick(["hull", "points", "hull_input", "hull_contains", "in_current_or_next", "segments_containing",
                  "locate", "centroids", "nearest_centroid_ahead", "segment_at", "centroid_control",
                  "chull_control"])
    k = d.count(0, len(seg)) if d.rng.random() < 0.9 else d.count(-3, 3)
    if op in ("hull", "points", "hull_input"):
        return getattr(seg, op)(k)
    if op == "hull_contains":
        return seg.hull_contains(k, d.points(scale=50.0))
    if op == "in_current_or_next":
        return seg.in_current_or_next(k, d.arr((2,), 50.0))
    if op in ("segments_containing", "nearest_centroid_ahead"):
        return getattr(seg, op)(d.arr((2,), 50.0))
    if op == "locate":
        return seg.locate(d.points(scale=50.0))
    if op == "centroids":
        return seg.centroids, seg.centroid_arc_lengths, seg.breaks
    if op == "segment_at":
        return seg.segment_at(d.num(-10, 200))
    est = d.state()
    if op == "centroid_control":
        return navigation.centroid_control(seg, est, d.pos(0.1, 5.0))
    return navigation.chull_control(seg, Bmm(d.params()), est, d.pos(0.1, 5.0), d.pos(0.5, 10.0), d.pos(0.1, 2.0))


def _hull(d: Draw):
    from safenav import geometry

    if d.rng.random() < 0.5:
        return geometry.convex_hull(d.points())
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    poly = square if d.rng.random() < 0.6 else d.points()
    return geometry.points_in_polygon(d.points(), poly)


def _constructors(d: Draw):
    from safenav import BmmParams, MeasurementKind, MeasurementModel, RiskZones

    op = int(d.rng.integers(3))
    if op == 0:
        return d.params()
    if op == 1:
        return RiskZones(half_width=d.pos(), weights=[d.pos() for _ in range(int(d.rng.integers(0, 5)))])
    kind = d._pick(list(MeasurementKind.__members__.values()))
    n = int(d.rng.integers(1, 6))
    m = MeasurementModel(kind, d.cov(n if d.rng.random() < 0.5 else 2), d.points(n))
    return m.dim, BmmParams()


# The online API under hostile timestamps: jumps (1e8, 1e12 s), repeats, steps
# back in time, 1e300, NaN.  Each input either raises an allowed error and
# leaves the localizer exactly as it was (time, estimate, covariance, counts),
# or returns with a finite estimate and a valid covariance (finite, symmetric,
# positive semi-definite; the EKF's positive definite).
LANDMARKS = np.array([[0.0, 0.0], [25.0, 0.0], [0.0, 25.0], [25.0, 25.0]])


def _timestamp(d: Draw, t: float) -> float:
    if d.rng.random() < 0.2:
        kind = int(d.rng.integers(7))
        v = [t + 1e8, t + 1e12, t, t - 5.0, 1e300, -1e300, t + 1e-12][kind]
        return d._note(v)
    return d._note(t + float(d.rng.uniform(0.01, 0.5)))


def _snapshot(loc):
    c = loc.counts
    return (loc.initialized, np.float64(loc.time).tobytes(), np.array(loc.x, dtype=float).tobytes(), np.array(loc.P, dtype=float).tobytes(),
            (c.motion, c.applied, c.rejected, c.late, c.buffered, c.resets))


def _check_estimate(loc, where):
    if not loc.initialized:
        return
    x, P = np.asarray(loc.x), np.asarray(loc.P)
    if not (np.isfinite(x).all() and np.isfinite(P).all() and np.isfinite(loc.position_std)):
        raise FloatingPointError(f"{where}: non-finite estimate x={x} P diag={np.diag(P)}")
    if np.abs(P - P.T).max() > 1e-9 * max(1.0, np.abs(P).max()):
        raise FloatingPointError(f"{where}: P is not symmetric")
    lam = np.linalg.eigvalsh(P).min()
    if lam < -1e-9 * max(1.0, np.abs(P).max()):
        raise FloatingPointError(f"{where}: P has a negative eigenvalue {lam}")


def _localizer(d: Draw):
    from safenav.guidance import Localizer, localizer_settings

    augment = [a for a in ("range_scale", "heading_rate_bias", "range_bias") if d.rng.random() < 0.3]
    s = localizer_settings(filter=d._pick(["ekf", "pf"]), n_particles=int(d.rng.integers(1, 60)),
                           seed=int(d.rng.integers(100)), augment=augment,
                           gate=d._pick([0.0, 0.99, None]))
    loc = Localizer(s, LANDMARKS)
    t = 0.0
    if d.rng.random() < 0.7:
        x0 = d.state()
        if isinstance(x0, np.ndarray) and x0.shape == (4,) and x0.dtype == np.float64 and d.rng.random() < 0.9:
            x0[:2] = np.abs(x0[:2]) + 5.0  # mostly inside the map
        loc.initialize(t, x0, d.cov(4))
    results = []
    for step in range(int(d.rng.integers(1, 25))):
        t = _timestamp(d, t)
        op = int(d.rng.integers(5))
        before = _snapshot(loc)
        try:
            if op == 0:
                r = loc.motion(t, d.num(0.0, 2.0), d.num(-0.3, 0.3))
            elif op == 1:
                r = loc.odometry(t, d.num(0.0, 1.0), d.num(-0.3, 0.3))
            elif op == 2:
                kw = {}
                if d.rng.random() < 0.8:
                    kw.update(range=d.pos(1.0, 40.0), range_std=d.pos(0.05, 2.0))
                if d.rng.random() < 0.4 or not kw:
                    kw.update(bearing=d.num(-3.0, 3.0), bearing_std=d.pos(0.01, 0.5))
                r = loc.observe(t, int(d.rng.integers(4)), **kw)
            elif op == 3:
                r = loc.fix(t, d.num(0.0, 25.0), d.num(0.0, 25.0), d.cov(2))
            else:
                r = loc.speed_heading(t, d.num(0.0, 2.0), d.num(-3.0, 3.0), d.pos(0.01, 1.0), d.pos(0.01, 1.0))
        except ALLOWED:
            if _snapshot(loc) != before:
                raise AssertionError(f"input {step} raised but changed the localizer") from None
            t = loc.time if math.isfinite(loc.time) else 0.0
            continue
        _check_estimate(loc, f"input {step}")
        results.append((r.nis if r.dim > 0 else 0.0, r.dim))
        if not math.isfinite(t):
            t = 0.0
    return loc.x if loc.initialized else 0.0, loc.P if loc.initialized else 0.0, loc.position_std if loc.initialized else 0.0, results


TARGETS = {"wrap_angle": _wrap_angle, "bmm": _bmm, "measurement": _measurement, "filter": _filter,
           "filter_trajectory": _filter_trajectory, "metrics": _metrics, "corridor": _corridor,
           "segments": _segments, "hull": _hull, "constructors": _constructors, "localizer": _localizer}
NAMES = sorted(TARGETS)
