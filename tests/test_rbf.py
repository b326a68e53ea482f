"""Gaussian RBF networks, composite learning step, projection and fault observer of the control kernels.

See docs/control_law.md#learning-and-estimation and #anti-windup-and-projection; checked against direct numpy
evaluations of the formulas.
"""
import math

import numpy as np
import pytest

from uh_controller_node.control_kernels import (
    PROJECTION_TOLERANCE,
    composite_weight_update,
    fault_observer_update,
    project_columns,
    rbf_activations,
    rbf_centre,
    rbf_output,
)


def activations(x, nodes, low, high, width):
    out = np.empty((nodes, 3))
    rbf_activations(np.asarray(x, float), low, high, width, out)
    return out


def numpy_activations(x, nodes, low, high, width):
    """S[i, a] = exp(-(x_a - c_i)^2 / b^2) with c = linspace(low, high, nodes)."""
    c = np.linspace(low, high, nodes) if nodes > 1 else np.array([0.5 * (low + high)])
    return np.exp(-(np.asarray(x, float)[None, :] - c[:, None]) ** 2 / width ** 2)


def numpy_projection(w, bound):
    norms = np.linalg.norm(w, axis=0)
    return w * np.minimum(1.0, bound / np.maximum(norms, 1e-300))


def test_centres_are_evenly_spaced_like_linspace():
    for nodes, low, high in ((5, -2.0, 2.0), (11, -4.0, 4.0), (7, -0.3, 1.9)):
        centres = [rbf_centre(i, nodes, low, high) for i in range(nodes)]
        assert np.array_equal(centres, np.linspace(low, high, nodes))      # same bits
    assert rbf_centre(0, 1, -1.0, 3.0) == 1.0


def test_activations_closed_form():
    s = activations([0.0, 1.0, 0.5], 5, -2.0, 2.0, 0.5)
    # centres -2, -1, 0, 1, 2; axis 0 sits on centre 2: S = 1 there and exp(-(1/0.5)^2) = e^-4 one
    # spacing away
    assert s[2, 0] == 1.0
    assert s[1, 0] == pytest.approx(math.exp(-4.0), rel=1e-15)
    # axis 2 halfway between centres 2 and 3: equal activations exp(-(0.5/0.5)^2) = e^-1
    assert s[2, 2] == pytest.approx(math.exp(-1.0), rel=1e-15)
    assert s[3, 2] == pytest.approx(s[2, 2], rel=1e-15)


def test_activations_and_output_match_numpy():
    rng = np.random.default_rng(1)
    for nodes, low, high, width in ((7, -3.0, 3.0, 1.0), (11, -2.0, 2.0, 0.6), (1, -1.0, 1.0, 0.8)):
        x = rng.uniform(-4.0, 4.0, size=3)
        w = rng.normal(size=(nodes, 3))
        s = activations(x, nodes, low, high, width)
        # the kernel multiplies by -1/b^2, numpy divides by b^2: the exponents y differ by a few
        # ulp, and exp turns that into a relative error of |y| ulp (|y| < 200 here)
        assert np.allclose(s, numpy_activations(x, nodes, low, high, width), rtol=1e-12, atol=0)
        out = np.empty(3)
        rbf_output(w, s, out)
        expected = [sum(w[i, a] * math.exp(-(x[a] - rbf_centre(i, nodes, low, high)) ** 2 / width ** 2)
                        for i in range(nodes)) for a in range(3)]
        assert np.allclose(out, expected, rtol=1e-13, atol=1e-15)


def test_basis_can_represent_a_smooth_function():
    # Lemma 3: on the covered range a least-squares fit of 11 nodes reproduces sin(1.5 x) closely
    xs = np.linspace(-2.0, 2.0, 201)
    phi = np.array([activations([x, x, x], 11, -2.0, 2.0, 0.6)[:, 0] for x in xs])
    coef, *_ = np.linalg.lstsq(phi, np.sin(1.5 * xs), rcond=None)
    err = np.abs(phi @ coef - np.sin(1.5 * xs))
    # 11 Gaussians 0.4 apart fit this sine to < 1 % of its amplitude inside the centres' span
    # (0.7 % measured) and < 3 % at the ends, where only one side has basis functions (2.4 %)
    assert np.max(err[np.abs(xs) <= 1.6]) < 1e-2
    assert np.max(err) < 3e-2


def test_projection_scales_only_the_columns_outside_the_ball():
    w = np.array([[3.0, 0.1, 0.0], [4.0, 0.1, 0.0]])     # column norms 5, 0.141, 0
    assert project_columns(w, 2.0)
    assert np.linalg.norm(w[:, 0]) == pytest.approx(2.0, rel=1e-14)
    assert np.allclose(w[:, 0] / np.linalg.norm(w[:, 0]), [0.6, 0.8])   # direction kept
    assert np.array_equal(w[:, 1], [0.1, 0.1]) and np.array_equal(w[:, 2], [0.0, 0.0])
    assert not project_columns(w, 2.0)


def test_projection_keeps_every_column_within_the_bound():
    rng = np.random.default_rng(7)
    for _ in range(200):
        w = rng.normal(scale=rng.uniform(0.1, 20.0), size=(11, 3))
        bound = rng.uniform(0.5, 10.0)
        before = w.copy()
        project_columns(w, bound)
        norms = np.linalg.norm(w, axis=0)
        assert np.all(norms <= bound * (1.0 + PROJECTION_TOLERANCE))
        inside = np.linalg.norm(before, axis=0) <= bound
        assert np.array_equal(w[:, inside], before[:, inside])
        # the Euclidean projection onto the ball, column by column (relative rounding)
        assert np.allclose(w, numpy_projection(before, bound), rtol=1e-14, atol=1e-15)


def test_composite_update_is_one_euler_step_of_the_law():
    s = activations([0.1, -0.4, 0.9], 4, -1.0, 1.0, 0.8)
    w = np.full((4, 3), 0.2)
    z, zn = np.array([0.3, -0.2, 0.05]), np.array([0.1, 0.4, -0.3])
    gamma_l, gamma, sigma, dt = 2.0, 1.5, 0.1, 0.01
    expected = w + dt * gamma_l * (s * (z + gamma * zn) - sigma * w)
    composite_weight_update(w, s, z, zn, gamma_l, gamma, sigma, dt, 100.0)
    assert np.allclose(w, expected, rtol=1e-14, atol=1e-16)


def test_composite_update_projects_after_the_step():
    rng = np.random.default_rng(3)
    s = activations([0.3, -1.1, 2.5], 11, -2.0, 2.0, 0.6)
    w = rng.normal(scale=3.0, size=(11, 3))
    z, zn = rng.normal(size=3) * 50.0, rng.normal(size=3) * 50.0
    gamma_l, gamma, sigma, dt, bound = 0.5, 20.0, 1.0, 0.01, 10.0
    expected = numpy_projection(w + dt * gamma_l * (s * (z + gamma * zn) - sigma * w), bound)
    composite_weight_update(w, s, z, zn, gamma_l, gamma, sigma, dt, bound)
    assert np.any(np.linalg.norm(expected, axis=0) > bound * 0.999)     # the projection acted
    assert np.allclose(w, expected, rtol=1e-13, atol=1e-14)


def test_fault_observer_is_one_euler_step_then_clipped():
    fhat = np.array([0.5, -4.99, 4.9])
    z, zn = np.array([0.2, -3.0, 3.0]), np.array([-0.1, -2.0, 2.0])
    lam, gamma_f, sigma_f, dt, bound = 10.0, 40.0, 0.01, 0.01, 5.0
    expected = np.clip(fhat + dt * lam * (z + gamma_f * zn - sigma_f * fhat), -bound, bound)
    fault_observer_update(fhat, z, zn, lam, gamma_f, sigma_f, dt, bound)
    assert np.allclose(fhat, expected, rtol=1e-15, atol=1e-15)
    assert fhat[1] == -bound and fhat[2] == bound and abs(fhat[0]) < bound


def test_learning_phase_trains_the_network_and_holds_the_observer():
    """Check estimator_advance in and after the learning phase.

    In the learning phase W takes one Euler step with (learning_rate, sigma) and Fhat does not move; afterwards W uses
    (late_learning_rate, late_sigma) and Fhat its law.
    """
    from uh_controller_node import control_kernels as ck
    params = np.zeros(ck.CONTROL_PARAMS_SIZE)
    base = ck.CP_INNER
    for offset, value in ((ck.L_KAPPA, 5.0), (ck.L_LEARNING_RATE, 2.0), (ck.L_GAMMA, 1.5),
                          (ck.L_SIGMA, 0.1), (ck.L_LATE_LEARNING_RATE, 0.02), (ck.L_LATE_SIGMA, 0.0),
                          (ck.L_LAMBDA, 10.0), (ck.L_GAMMA_F, 4.0), (ck.L_SIGMA_F, 0.01),
                          (ck.L_FAULT_BOUND, 30.0), (ck.L_WEIGHT_BOUND, 100.0)):
        params[base + offset] = value
    s = activations([0.1, -0.4, 0.9], 4, -1.0, 1.0, 0.8)
    z, zn, dt = np.array([0.3, -0.2, 0.05]), np.array([0.1, 0.4, -0.3]), 0.01
    zero = np.zeros(3)
    for learning, rate, sigma in ((True, 2.0, 0.1), (False, 0.02, 0.0)):
        w, fhat, xhat = np.full((4, 3), 0.2), np.array([0.5, -0.5, 0.1]), np.zeros(3)
        expected_w = w + dt * rate * (s * (z + 1.5 * zn) - sigma * w)
        expected_f = fhat if learning else fhat + dt * 10.0 * (z + 4.0 * zn - 0.01 * fhat)
        ck.estimator_advance(params, base, dt, learning, zero, zero, zero, z, zn, s, xhat, w, fhat)
        assert np.allclose(w, expected_w, rtol=1e-14, atol=1e-16), learning
        assert np.allclose(fhat, expected_f, rtol=1e-15, atol=1e-15), learning


def test_the_learning_phase_ends_after_its_duration_of_steps():
    """uh_control_step keeps the step's simulated time in memory; the phase ends once it reaches learning_phase."""
    from uh_controller_node import control_kernels as ck
    params = np.zeros(ck.CONTROL_PARAMS_SIZE)
    params[ck.CP_LEARNING_PHASE] = 0.05
    memory = np.zeros((ck.MEMORY_ROWS, 3))
    flags = []
    for _ in range(7):
        flags.append(bool(ck.in_learning_phase(params, memory)))
        memory[ck.M_FLAGS, ck.FLAG_TIME] += 0.01
    # 0.00 .. 0.04 inside; 0.05 (five additions of 0.01, which rounds just above 0.05) and later out
    assert flags == [True] * 5 + [False] * 2
