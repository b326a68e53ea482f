"""Gaussian radial-basis-function networks, one scalar network per axis (DESIGN.md 2.4 step 3, Lemma 3).

Each axis ``a`` of a 3-vector input ``x`` has its own scalar network with the same centres::

    S_i(x_a) = exp(-(x_a - c_i)^2 / b^2),   i = 1..mu
    fhat_a(x) = sum_i W[i, a] S_i(x_a)

so the activations and the weights are ``(mu, 3)`` arrays (column ``a`` belongs to axis ``a``).
This is the per-direction form of the paper ("the design processes of three directions are
similar"); it keeps the networks small (3 mu weights per loop) and the update cheap.

The weights are trained by the composite learning law of DESIGN.md 2.4 step 5 (see
:func:`composite_weight_update`), with the discrete projection that keeps each column in a ball.
"""
from __future__ import annotations

import numpy as np

__all__ = ['RBFError', 'GaussianRBF', 'composite_weight_update', 'project_columns']


class RBFError(ValueError):
    """Invalid RBF layer definition or input shape."""


class GaussianRBF:
    """A layer of ``mu`` Gaussian basis functions applied to each of the 3 axes of an input.

    Parameters
    ----------
    nodes : int
        Number of centres mu (>= 1).
    low, high : float
        First and last centre; centres are ``linspace(low, high, nodes)`` (one centre at
        ``(low + high) / 2`` when ``nodes == 1``).
    width : float
        Width b > 0 (same unit as the input).

    Notes
    -----
    :meth:`activations` writes into a buffer owned by the layer and returns it: the result is
    valid until the next call. Copy it if it must be kept.
    """

    def __init__(self, nodes: int, low: float, high: float, width: float):
        if isinstance(nodes, bool) or not isinstance(nodes, (int, np.integer)) or nodes < 1:
            raise RBFError(f'RBF node count must be an integer >= 1, got {nodes!r}')
        if not np.isfinite(width) or width <= 0.0:
            raise RBFError(f'RBF width must be a finite number > 0, got {width!r}')
        if not (np.isfinite(low) and np.isfinite(high)) or (nodes > 1 and not low < high):
            raise RBFError(f'RBF centres need finite low < high, got low={low!r}, high={high!r}')
        if nodes == 1:
            self.centres = np.array([0.5 * (low + high)])
        else:
            self.centres = np.linspace(float(low), float(high), int(nodes))
        self.width = float(width)
        self._c = self.centres.reshape(-1, 1)          # (mu, 1), broadcast against (3,)
        self._neg_inv_b2 = -1.0 / (self.width * self.width)
        self._buf = np.empty((self.centres.size, 3))

    @property
    def activations_buffer(self) -> np.ndarray:
        """The buffer the last :meth:`activations` call wrote (mu, 3)."""
        return self._buf

    @property
    def nodes(self) -> int:
        """Number of centres mu."""
        return self.centres.size

    def activations(self, x) -> np.ndarray:
        """``S`` (mu, 3) with ``S[i, a] = exp(-(x[a] - c_i)^2 / b^2)`` for input ``x`` (3,)."""
        s = self._buf
        np.subtract(x, self._c, out=s)
        np.multiply(s, s, out=s)
        np.multiply(s, self._neg_inv_b2, out=s)
        np.exp(s, out=s)
        return s

    @staticmethod
    def output(weights: np.ndarray, activations: np.ndarray) -> np.ndarray:
        """Network output ``W^T S`` per axis, (3,): ``sum_i W[i, a] S[i, a]``."""
        return np.einsum('ij,ij->j', weights, activations)

    def evaluate(self, weights: np.ndarray, x) -> list:
        """``W^T S(x)`` for input ``x`` (3,) as a list of 3 floats (activations left in the buffer)."""
        return (weights * self.activations(x)).sum(axis=0).tolist()


def project_columns(weights: np.ndarray, bound: float) -> bool:
    """Scale in place every column of ``weights`` (mu, 3) whose norm exceeds ``bound``.

    The discrete counterpart of the projection operator: the result is the Euclidean projection
    of each column onto the ball of radius ``bound``. Returns True if any column was scaled.
    """
    norms2 = np.einsum('ij,ij->j', weights, weights)
    # a column scaled onto the sphere may round to a hair above it: that counts as inside
    if norms2.max() <= bound * bound * (1.0 + 1e-12):
        return False
    norms = np.sqrt(norms2)
    weights *= np.minimum(1.0, bound / np.maximum(norms, 1e-300))
    return True


def composite_weight_update(weights: np.ndarray, activations: np.ndarray, tracking_error,
                            prediction_error, learning_rate: float, gamma: float, sigma: float,
                            dt: float, bound: float) -> None:
    """One explicit-Euler step of the composite learning law, in place (DESIGN.md 2.4 step 5).

    ``W' = Gamma [ S (z + gamma z_n)^T - sigma W ]`` per axis, i.e. column ``a`` of ``W`` moves by
    ``dt Gamma (S[:, a] (z[a] + gamma z_n[a]) - sigma W[:, a])``; then :func:`project_columns`.

    Parameters
    ----------
    weights : ndarray (mu, 3)
        W, updated in place.
    activations : ndarray (mu, 3)
        S(X) at the current step.
    tracking_error, prediction_error : sequence of 3 float
        z (z2 or z4) and z_n (SPEM prediction error) at the current step.
    learning_rate, gamma, sigma : float
        Gamma 1/s, gamma (-), sigma (-).
    dt : float
        Step, s.
    bound : float
        Projection radius of each column.
    """
    step = dt * learning_rate
    drive = [step * (float(z) + gamma * float(e)) for z, e in zip(tracking_error, prediction_error)]
    # W <- (1 - dt Gamma sigma) W + dt Gamma S diag(z + gamma z_n)
    if sigma != 0.0:
        weights *= 1.0 - step * sigma
    weights += activations * drive
    project_columns(weights, bound)
