"""The Battlefield Motion Model (SafeNav paper, eqs. 3–9).

State ``x = (x, y, v, θ)``, control ``u = (desired speed, heading change)``.

* eq. 3 — speed: ``min(v + aΔt, v_desired, v_max)`` when speeding up,
  ``max(v − dΔt, v_desired, 0)`` when slowing down;
* eq. 4 — heading: ``θ + clip(Δθ, −mΔt, mΔt)``, wrapped to (−π, π];
* eq. 7 — position uses the *updated* speed and heading;
* eqs. 8–9 — terrain: we read τ as metres of extra equivalent travel per
  metre of ground, so one step covers ``v·Δt/(1+τ)`` (τ = 0 gives eq. 7).
  The paper's λ = τ/v_c is then the delay per metre at cruise speed v_c; the
  paper does not say how τ enters a single step, so this is our reading;
* eq. 6 — process noise ε = (ε_x, ε_y, ε_v, ε_θ) enters the noisy transition
  ``transition``/``simulate``; the filters use ``Q = G Σ_ε Gᵀ`` with the noise
  Jacobian G (the paper leaves Q unspecified).

Parameter defaults are ours: the paper gives no values.  Finite inputs whose
result overflows (a state near 1e308, dt = 1e308) raise ``ValueError`` naming
the result entry and the inputs; no call returns inf or NaN.
"""

from __future__ import annotations

import numpy as np

from . import _core
from .validation import as_array, as_seed

BmmParams = _core.BmmParams


def wrap_angle(angle):
    """Wrap angles to (−π, π] (DESIGN decision 2: every angle residual is wrapped).

    A number gives a float, an array an array of the same shape.  Raises
    ``TypeError`` for non-numbers and ``ValueError`` naming a NaN or inf."""
    try:
        a = np.asarray(angle)
    except ValueError:  # ragged nested sequences
        raise TypeError(f"angle must be a number or an array of numbers, got {type(angle).__name__}") from None
    if a.dtype.kind not in "iuf":  # None would become NaN through float64
        raise TypeError(f"angle must be a number or an array of numbers, got {type(angle).__name__} ({a.dtype})")
    a = a.astype(np.float64)
    bad = ~np.isfinite(a)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"angle{list(where) if where else ''} = {a[where]} is not finite")
    return _core.wrap_angle(a)


class Bmm(_core.Bmm):
    """The BMM transition ``f(x, u)`` with analytic Jacobians (eqs. 3–9)."""

    def next_speed(self, v: float, desired_speed: float) -> float:
        """Eq. 3: the next speed from speed ``v`` and the desired speed."""
        as_array("(v, desired_speed)", (v, desired_speed), (2,))
        return super().next_speed(v, desired_speed)

    def clipped_heading_change(self, heading_change: float) -> float:
        """Eq. 4: the heading change clipped to ±m·Δt."""
        as_array("heading_change", (heading_change,), (1,))
        return super().clipped_heading_change(heading_change)

    def predict(self, x, u) -> np.ndarray:
        """Deterministic ``f(x, u)`` (eqs. 3, 4, 7)."""
        return super().predict(as_array("x", x, (4,)), as_array("u", u, (2,)))

    def jacobian(self, x, u) -> np.ndarray:
        """``F = ∂f/∂x`` at ``(x, u)`` (the EKF's F_k of eq. 11)."""
        return super().jacobian(as_array("x", x, (4,)), as_array("u", u, (2,)))

    def noise_jacobian(self, x, u) -> np.ndarray:
        """``G = ∂f/∂ε`` for ε = (ε_x, ε_y, ε_v, ε_θ) (eqs. 6–7)."""
        return super().noise_jacobian(as_array("x", x, (4,)), as_array("u", u, (2,)))

    def process_cov(self, x, u) -> np.ndarray:
        """``Q = G Σ_ε Gᵀ`` (eq. 11's Q_k)."""
        return super().process_cov(as_array("x", x, (4,)), as_array("u", u, (2,)))

    def transition(self, x, u, eps) -> np.ndarray:
        """Noisy transition with explicit noise ε = (ε_x, ε_y, ε_v, ε_θ) (eqs. 6–9)."""
        return super().transition(as_array("x", x, (4,)), as_array("u", u, (2,)), as_array("eps", eps, (4,)))

    def simulate(self, x0, controls, seed: int = 0) -> np.ndarray:
        """Simulate the true vehicle: ``(N+1, 4)`` states from ``N`` controls, seeded."""
        return super().simulate(as_array("x0", x0, (4,)), as_array("controls", controls, (None, 2)),
                                as_seed("seed", seed))
