"""Kernels of the law's learning: Gaussian RBF networks, composite learning, fault observers.

The networks, their column projection, the composite weight law, the fault estimation observer and
the serial-parallel estimation model that drives both (docs/control_law.md#learning-and-estimation,
#anti-windup-and-projection and #learning-phase), for either loop: :func:`estimator_advance` reads
the gains of the loop whose block of ``params`` starts at ``base`` (``PARAM.outer`` or
``PARAM.inner``, :mod:`.control_layout`). Called by the loops (:mod:`.loop_kernels`) once per step.

Compiled with numba as :mod:`.control_kernels` describes (no fastmath: IEEE double arithmetic, in
the order written), and ahead of time with the other kernel modules (docs/performance.md#memory).
"""
from __future__ import annotations

import math

from uh_core import compiled_kernels as _compiled_kernels
from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_core.compiled_kernels import njit

from . import control_layout as _control_layout
from . import gains as _gains
from .control_layout import FLAG_TIME, LOOP, M_FLAGS, PARAM

__all__ = ['PROJECTION_TOLERANCE', 'rbf_centre', 'rbf_activations', 'rbf_output', 'project_columns',
           'composite_weight_update', 'fault_observer_update', 'in_learning_phase', 'estimator_advance',
           'frobenius_norm']

#: Relative slack of the column-norm test of :func:`project_columns`: a column scaled onto the
#: sphere may round to a hair above it, and that counts as inside.
PROJECTION_TOLERANCE = 1e-12

_TINY_NORM = 1e-300         # guards the division by a zero column norm in the projection


# =============================================================================================
# Gaussian RBF networks, composite learning, fault observers
# (docs/control_law.md#learning-and-estimation and #anti-windup-and-projection)


@njit(cache=True)
def rbf_centre(i, nodes, low, high):
    """Return the centre c_i of node ``i`` of ``nodes`` evenly spaced on ``[low, high]``.

    The spacing is that of ``np.linspace``; one node sits at ``(low + high) / 2``.
    """
    if nodes == 1:
        return 0.5 * (low + high)
    if i == nodes - 1:
        return high
    return i * ((high - low) / (nodes - 1)) + low


@njit(cache=True)
def rbf_activations(x, low, high, width, out):
    """Gaussian activations of one scalar network per axis, all with the same centres.

    Each axis ``a`` of a 3-vector input ``x`` has its own scalar network (the per-direction form
    of the paper, "the design processes of three directions are similar")::

        S_i(x_a) = exp(-(x_a - c_i)^2 / b^2),   i = 1..mu,   c_i evenly spaced on [low, high]

    Parameters
    ----------
    x : ndarray (3,)
        Network input (velocity m/s or body rate rad/s).
    low, high, width : float
        First and last centre, width b > 0 (unit of ``x``).
    out : ndarray (mu, 3)
        ``S[i, a] = S_i(x_a)``; mu is ``out.shape[0]``.
    """
    nodes = out.shape[0]
    neg_inv_b2 = -1.0 / (width * width)
    for i in range(nodes):
        c = rbf_centre(i, nodes, low, high)
        for a in range(3):
            s = x[a] - c
            out[i, a] = math.exp(s * s * neg_inv_b2)


@njit(cache=True)
def rbf_output(weights, activations, out):
    """Network output per axis ``fhat_a = sum_i W[i, a] S[i, a]`` (i.e. ``W^T S``), to ``out`` (3,).

    ``weights`` and ``activations`` are (mu, 3); the sum runs over i in ascending order.
    """
    for a in range(3):
        acc = 0.0
        for i in range(weights.shape[0]):
            acc += weights[i, a] * activations[i, a]
        out[a] = acc


@njit(cache=True)
def project_columns(weights, bound):
    """Scale in place every column of ``weights`` (mu, 3) whose Euclidean norm exceeds ``bound``.

    The discrete counterpart of the projection operator (docs/control_law.md#anti-windup-and-projection):
    each column is projected onto the ball of radius ``bound``, its direction kept. Returns True if any
    column was scaled.
    Columns within ``bound (1 + PROJECTION_TOLERANCE)`` are left unchanged.
    """
    limit = bound * bound * (1.0 + PROJECTION_TOLERANCE)
    scaled = False
    for a in range(3):
        norm2 = 0.0
        for i in range(weights.shape[0]):
            norm2 += weights[i, a] * weights[i, a]
        if norm2 > limit:
            scale = bound / max(math.sqrt(norm2), _TINY_NORM)
            for i in range(weights.shape[0]):
                weights[i, a] *= scale
            scaled = True
    return scaled


@njit(cache=True)
def composite_weight_update(weights, activations, z, zn, learning_rate, gamma, sigma, dt, bound):
    """Advance ``weights`` by one explicit-Euler step of the composite learning law, in place.

    The law is step 5 of docs/control_law.md#outer-loop::

        W' = Gamma [ S (z + gamma z_n)^T - sigma W ]        then the column projection

    per axis: column ``a`` of W moves by ``dt Gamma (S[:, a] (z[a] + gamma z_n[a]) - sigma W[:, a])``,
    i.e. ``W <- (1 - dt Gamma sigma) W + dt Gamma S diag(z + gamma z_n)``; then
    :func:`project_columns` with ``bound``.

    Parameters
    ----------
    weights : ndarray (mu, 3)
        W, updated in place.
    activations : ndarray (mu, 3)
        S(X) at t_k.
    z, zn : ndarray (3,)
        Tracking error (z2 or z4) and SPEM prediction error z_n at t_k.
    learning_rate, gamma, sigma : float
        Gamma 1/s, gamma (-), sigma (-).
    dt : float
        Step, s.
    bound : float
        Projection radius of each column.
    """
    step = dt * learning_rate
    leak = 1.0 - step * sigma
    for a in range(3):
        drive = step * (z[a] + gamma * zn[a])
        for i in range(weights.shape[0]):
            w = weights[i, a]
            if sigma != 0.0:
                w = w * leak
            weights[i, a] = w + activations[i, a] * drive
    project_columns(weights, bound)


@njit(cache=True)
def fault_observer_update(fhat, z, zn, lambda_, gamma_f, sigma_f, dt, bound):
    """Advance ``fhat`` by one explicit-Euler step of the fault estimation observer, in place.

    The observer is step 6 of docs/control_law.md#outer-loop::

        Fhat' = lambda [ z + gamma_F z_n - sigma_F Fhat ]     then |Fhat_a| <= bound per component

    ``fhat``, ``z``, ``zn`` (3,); ``lambda_`` 1/s, ``gamma_f``, ``sigma_f`` (-), ``dt`` s.
    """
    gain = dt * lambda_
    for a in range(3):
        f = fhat[a] + gain * (z[a] + gamma_f * zn[a] - sigma_f * fhat[a])
        fhat[a] = min(max(f, -bound), bound)


@njit(cache=True)
def in_learning_phase(params, memory):
    """Return True while the step's simulated time (``FLAG_TIME``) is within the learning phase.

    The learning phase (``PARAM.learning_phase``) is counted from step 0 of the run.
    """
    return memory[M_FLAGS, FLAG_TIME] < params[PARAM.learning_phase]


@njit(cache=True)
def estimator_advance(params, base, dt, learning, drift, net, applied, z, zn, activations, estimate, weights, fhat):
    """Advance the learning states of one loop from t_k to t_{k+1}.

    Explicit Euler (docs/control_law.md#outer-loop steps 4-6 and 2.5 step 3), all right-hand sides at t_k::

        xhat' = f_nom + W^T S + a_applied + Fhat + kappa z_n      serial-parallel estimation model
        W'    = Gamma [ S (z + gamma z_n)^T - sigma W ]            composite learning, projection
        Fhat' = lambda [ z + gamma_F z_n - sigma_F Fhat ]          fault observer, projection

    ``a_applied`` is what the limits let through (anti-windup,
    docs/control_law.md#anti-windup-and-projection): the SPEM never learns an acceleration that was
    demanded but not delivered.

    During the learning phase (``learning``) the network learns with Gamma and sigma and the fault
    observer holds Fhat (zero from the start): what the nominal model misses goes into W. After it,
    the network goes on with the late Gamma and sigma, and the observer runs
    (docs/control_law.md#learning-phase).

    Parameters
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    base : int
        ``PARAM.outer`` (xhat = vhat, z = z2) or ``PARAM.inner`` (xhat = omegahat, z = z4).
    dt : float
        s.
    learning : bool
        True during the learning phase.
    drift, net, applied : ndarray (3,)
        f_nom, W^T S and a_applied at t_k (m/s^2 or rad/s^2).
    z, zn : ndarray (3,)
        Tracking and prediction errors at t_k.
    activations : ndarray (mu, 3)
        S at t_k.
    estimate, weights, fhat : ndarray (3,), (mu, 3), (3,)
        xhat, W, Fhat, updated in place.
    """
    kappa = params[base + LOOP.kappa]
    for a in range(3):
        estimate[a] = estimate[a] + dt * (drift[a] + net[a] + applied[a] + fhat[a] + kappa * zn[a])
    if learning:
        composite_weight_update(weights, activations, z, zn, params[base + LOOP.learning_rate],
                                params[base + LOOP.gamma], params[base + LOOP.sigma], dt,
                                params[base + LOOP.weight_bound])
        return
    composite_weight_update(weights, activations, z, zn, params[base + LOOP.late_learning_rate],
                            params[base + LOOP.gamma], params[base + LOOP.late_sigma], dt,
                            params[base + LOOP.weight_bound])
    fault_observer_update(fhat, z, zn, params[base + LOOP.lambda_], params[base + LOOP.gamma_F],
                          params[base + LOOP.sigma_F], dt, params[base + LOOP.fault_bound])


@njit(cache=True)
def frobenius_norm(weights):
    """``sqrt(sum_ia W[i, a]^2)`` of a (mu, 3) weight matrix."""
    acc = 0.0
    for i in range(weights.shape[0]):
        for a in range(3):
            acc += weights[i, a] * weights[i, a]
    return math.sqrt(acc)


# numba caches each kernel by this file only: empty the cache when a table it reads changes
_kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()),
                            [_layout.__file__, _gains.__file__, _control_layout.__file__])

# run the ahead-of-time compiled kernels instead where this process asks for them (docs/performance.md#memory)
_compiled_kernels.install(globals())
