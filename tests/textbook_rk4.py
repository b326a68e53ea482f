"""Classical RK4 written out plainly, the independent reference of the model tests."""


def rk4(f, x, t, dt, substeps):
    """Integrate ``x' = f(tt, x, ts)`` from ``t`` over ``dt`` in ``substeps`` RK4 steps.

    ``ts`` is the start time of the substep (the time at which fault activity is decided), ``tt`` the stage time.
    """
    h = dt / substeps
    for s in range(substeps):
        ts = t + s * h
        k1 = f(ts, x, ts)
        k2 = f(t + (s + 0.5) * h, x + h / 2 * k1, ts)
        k3 = f(t + (s + 0.5) * h, x + h / 2 * k2, ts)
        k4 = f(t + (s + 1) * h, x + h * k3, ts)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x
