"""MeasurementModel.residuals: the batch residual z ⊖ h(x_i) that the particle
filters, the EKF's direct updates and the smoother share (eq. 10's residual,
angle components wrapped), against the model's own per-state predict and
residual, exactly."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from safenav import MeasurementModel, wrap_angle

LANDMARKS = np.array([[10.0, 0.0], [-3.0, 7.5], [0.0, -12.0]])
R2 = np.array([[0.25, 0.05], [0.05, 0.16]])

MODELS = {
    "position": MeasurementModel.position(R2),
    "speed_heading": MeasurementModel.speed_heading(R2),
    "range": MeasurementModel.range(LANDMARKS, 0.3),
    "bearing": MeasurementModel.bearing(LANDMARKS, 0.05),
    "range_bearing": MeasurementModel.range_bearing(LANDMARKS, 0.3, 0.05),
}

# headings on and around ±π and 0, where the wrapped residual turns over
ANGLES = st.one_of(st.floats(-np.pi, np.pi), st.sampled_from([np.pi, -np.pi, 0.0, np.nextafter(np.pi, 0.0),
                                                              np.nextafter(-np.pi, 0.0)]))
STATE = st.tuples(st.floats(-30, 30), st.floats(-30, 30), st.floats(-2, 6), ANGLES)


def _per_state(model, z, states):
    return np.array([model.residual(z, model.predict(x)) for x in states]).reshape(len(states), model.dim)


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(sorted(MODELS)), states=st.lists(STATE, min_size=1, max_size=12),
       zs=st.lists(st.one_of(st.floats(-40, 40), ANGLES), min_size=6, max_size=6))
def test_residuals_are_the_models_per_state_residuals_bit_for_bit(name, states, zs):
    model = MODELS[name]
    x = np.array(states, dtype=float)
    # a state on a landmark has no bearing (predict refuses it): move it off
    x[:, :2] += 1e-3 * (np.min(np.linalg.norm(x[:, None, :2] - LANDMARKS[None], axis=2), axis=1) < 1e-6)[:, None]
    z = np.array(zs[:model.dim], dtype=float)
    for i in range(model.dim):
        if model.is_angle(i):
            z[i] = wrap_angle(z[i])
    got = model.residuals(z, x)
    assert got.shape == (len(x), model.dim)
    np.testing.assert_array_equal(got, _per_state(model, z, x))


def test_speed_heading_residuals_wrap_theta_and_position_residuals_do_not():
    """Eq. 10's residual: z − h(x), h = (v, θ) with θ's residual wrapped into
    (−π, π]; position (x, y) is not an angle."""
    x = np.array([[0.0, 0.0, 2.0, 3.1], [5.0, -1.0, 0.5, -3.1], [1.0, 2.0, 1.0, np.pi]])
    z = np.array([1.5, -3.1])
    y = MODELS["speed_heading"].residuals(z, x)
    np.testing.assert_allclose(y[:, 0], 1.5 - x[:, 2], rtol=0, atol=0)
    np.testing.assert_allclose(y[:, 1], [2 * np.pi - 6.2, 0.0, -3.1 - np.pi + 2 * np.pi], atol=1e-15)
    assert np.all((y[:, 1] > -np.pi) & (y[:, 1] <= np.pi))
    zp = np.array([4.0, 9.0])
    np.testing.assert_array_equal(MODELS["position"].residuals(zp, x), zp - x[:, :2])


def test_residuals_name_bad_input():
    model = MODELS["speed_heading"]
    with pytest.raises(ValueError, match="2 entries"):
        model.residuals(np.array([1.0, 2.0, 3.0]), np.zeros((2, 4)))
    with pytest.raises(ValueError, match="not finite"):
        model.residuals(np.array([np.nan, 0.0]), np.zeros((2, 4)))
    with pytest.raises(ValueError, match="states must be finite"):
        model.residuals(np.array([1.0, 0.0]), np.array([[0.0, 0.0, np.inf, 0.0]]))
    assert model.residuals(np.array([1.0, 0.0]), np.zeros((0, 4))).shape == (0, 2)
