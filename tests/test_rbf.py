"""Gaussian RBF layer, composite learning step and projection (DESIGN.md 2.4 steps 3 and 5, 2.5a)."""
import math

import numpy as np
import pytest

from uh_controller_node.rbf import GaussianRBF, RBFError, composite_weight_update, project_columns


def test_activations_closed_form():
    net = GaussianRBF(5, -2.0, 2.0, 0.5)
    assert np.allclose(net.centres, [-2.0, -1.0, 0.0, 1.0, 2.0])
    s = net.activations(np.array([0.0, 1.0, 0.5]))
    assert s.shape == (5, 3)
    # axis 0 sits on centre 0: S = 1 there and exp(-(1/0.5)^2) = e^-4 one spacing away
    assert s[2, 0] == 1.0
    assert s[1, 0] == pytest.approx(math.exp(-4.0), rel=1e-15)
    # axis 2 halfway between centres 0 and 1: equal activations exp(-(0.5/0.5)^2) = e^-1
    assert s[2, 2] == pytest.approx(math.exp(-1.0), rel=1e-15)
    assert s[3, 2] == pytest.approx(s[2, 2], rel=1e-15)


def test_output_is_per_axis_weighted_sum():
    net = GaussianRBF(7, -3.0, 3.0, 1.0)
    rng = np.random.default_rng(1)
    w = rng.normal(size=(7, 3))
    x = np.array([0.3, -1.2, 2.2])
    s = net.activations(x).copy()
    expected = [sum(w[i, a] * math.exp(-(x[a] - net.centres[i]) ** 2) for i in range(7)) for a in range(3)]
    assert np.allclose(net.output(w, s), expected, rtol=1e-13, atol=0)


def test_basis_can_represent_a_smooth_function():
    # Lemma 3: on the covered range a least-squares fit of 11 nodes reproduces sin(1.5 x) closely
    net = GaussianRBF(11, -2.0, 2.0, 0.6)
    xs = np.linspace(-2.0, 2.0, 201)
    phi = np.array([net.activations(np.array([x, x, x]))[:, 0].copy() for x in xs])
    coef, *_ = np.linalg.lstsq(phi, np.sin(1.5 * xs), rcond=None)
    err = np.abs(phi @ coef - np.sin(1.5 * xs))
    # 11 Gaussians 0.4 apart fit this sine to < 1 % of its amplitude inside the centres' span
    # (0.7 % measured) and < 3 % at the ends, where only one side has basis functions (2.4 %)
    assert np.max(err[np.abs(xs) <= 1.6]) < 1e-2
    assert np.max(err) < 3e-2


@pytest.mark.parametrize('kwargs, match', [
    (dict(nodes=0, low=-1.0, high=1.0, width=1.0), 'node count must be an integer >= 1'),
    (dict(nodes=3, low=1.0, high=-1.0, width=1.0), 'finite low < high'),
    (dict(nodes=3, low=-1.0, high=1.0, width=0.0), 'width must be a finite number > 0'),
])
def test_invalid_layers_are_rejected(kwargs, match):
    with pytest.raises(RBFError, match=match):
        GaussianRBF(**kwargs)


def test_projection_scales_only_the_columns_outside_the_ball():
    w = np.array([[3.0, 0.1, 0.0], [4.0, 0.1, 0.0]])     # column norms 5, 0.141, 0
    assert project_columns(w, 2.0)
    assert np.linalg.norm(w[:, 0]) == pytest.approx(2.0, rel=1e-14)
    assert np.allclose(w[:, 0] / np.linalg.norm(w[:, 0]), [0.6, 0.8])   # direction kept
    assert np.array_equal(w[:, 1], [0.1, 0.1]) and np.array_equal(w[:, 2], [0.0, 0.0])
    assert not project_columns(w, 2.0)


def test_composite_update_is_one_euler_step_of_the_law():
    net = GaussianRBF(4, -1.0, 1.0, 0.8)
    w = np.full((4, 3), 0.2)
    s = net.activations(np.array([0.1, -0.4, 0.9])).copy()
    z, zn = np.array([0.3, -0.2, 0.05]), np.array([0.1, 0.4, -0.3])
    gamma_l, gamma, sigma, dt = 2.0, 1.5, 0.1, 0.01
    expected = w + dt * gamma_l * (s * (z + gamma * zn) - sigma * w)
    composite_weight_update(w, s, z, zn, gamma_l, gamma, sigma, dt, bound=100.0)
    assert np.allclose(w, expected, rtol=1e-14, atol=1e-16)
