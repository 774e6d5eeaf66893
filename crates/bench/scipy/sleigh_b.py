#!/usr/bin/env python3
"""Formulation B on the sleigh by SciPy: the peer of `sleigh-floor`.

What a researcher would write with NumPy and SciPy for the same problem
the workbench solves: the state (x, y, phi, xdot, ydot, phidot), and at
every right-hand side the KKT system of d'Alembert-Lagrange with the
blade's multiplier,

    [ M   G^T ] [ qdd ]   [  Q      ]
    [ G   0   ] [ mu  ] = [ -gdot_0 ],

assembled from the sleigh's Lagrangian (scenes/src/sleigh.rs)

    L = m/2 (xd^2 + yd^2 + j phid^2 + 2 a phid (yd cos phi - xd sin phi))
        + m g sin(alpha) (x + com * a cos phi),

with the blade g = yd cos phi - xd sin phi, and solved by
LAPACK (dgesv); integrated by scipy.integrate.solve_ivp with DOP853
(Hairer's method, as the workbench's) at rtol = atol = tol.

The script reads one tolerance per line from stdin, runs solve_ivp once at
each, and answers each with one CSV line

    tol,error,rhs_evals,ms

until stdin closes. error = max |(x, y, phi)(t_end) - reference| (t_end is
a step point of solve_ivp: no dense output is read), ms the wall time of
`solve_ivp` alone (interpreter start and imports are not timed).
`sleigh-floor --scipy PYTHON` keeps one such process and times it in turn
with its own runs, one run each.
"""

import argparse
import math
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg.lapack import dgesv


def sleigh_rhs(m, j, a, gs, com):
    """The right-hand side f(t, y) of B with a generic KKT solve.

    Written as a careful NumPy user would: scalar trigonometry from `math`,
    the KKT matrix and vectors allocated once and filled in place, and
    LAPACK's dgesv (LU with partial pivoting, as the workbench's) called
    directly: 2.5 us here against 15 us through numpy.linalg.solve, whose
    overhead would otherwise dominate a 4 x 4 solve.
    """
    mgs = m * gs
    kkt = np.zeros((4, 4))
    kkt[0, 0] = kkt[1, 1] = m
    kkt[2, 2] = m * j
    rhs = np.zeros(4)
    dy = np.zeros(6)

    def f(_t, y):
        phi, xd, yd, phid = y[2], y[3], y[4], y[5]
        s, c = math.sin(phi), math.cos(phi)
        # M (the constant entries are set above) and G = (-s, c, 0).
        kkt[0, 2] = kkt[2, 0] = -m * a * s
        kkt[1, 2] = kkt[2, 1] = m * a * c
        kkt[3, 0] = kkt[0, 3] = -s
        kkt[3, 1] = kkt[1, 3] = c
        # Q = dL/dq - (d2L/dqd dq) qd (no explicit time dependence), and
        # -gdot_0 = -(dg/dq) qd.
        rhs[0] = mgs + m * a * phid * phid * c
        rhs[1] = m * a * phid * phid * s
        rhs[2] = -com * mgs * a * s
        rhs[3] = phid * (yd * s + xd * c)
        _, _, sol, info = dgesv(kkt, rhs)
        if info != 0:
            raise np.linalg.LinAlgError(f"KKT matrix singular (dgesv info {info})")
        dy[:3] = y[3:]
        dy[3:] = sol[:3]
        return dy.copy()

    return f


def solve_once(f, args, tol):
    """(error, rhs evaluations, ms) of one solve_ivp run at tol."""
    start = time.perf_counter()
    sol = solve_ivp(
        f,
        (0.0, args.t_end),
        np.array(args.y0),
        method="DOP853",
        rtol=tol,
        atol=tol,
    )
    ms = (time.perf_counter() - start) * 1e3
    if sol.status != 0:
        raise SystemExit(f"solve_ivp failed at tol {tol:e}: {sol.message}")
    end = sol.y[:3, -1]
    error = max(abs(end[i] - args.reference[i]) for i in range(3))
    return error, sol.nfev, ms


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for name in ("m", "j", "a", "gs", "com", "t-end"):
        p.add_argument("--" + name, type=float, required=True)
    p.add_argument("--y0", type=float, nargs=6, required=True)
    p.add_argument("--reference", type=float, nargs=3, required=True)
    args = p.parse_args()
    f = sleigh_rhs(args.m, args.j, args.a, args.gs, args.com)
    for line in sys.stdin:
        tol = float(line)
        if not tol > 0.0:
            raise SystemExit(f"tolerance must be positive, got {line.strip()}")
        error, nfev, ms = solve_once(f, args, tol)
        print(f"{tol:e},{error:.3e},{nfev},{ms:.4f}", flush=True)


if __name__ == "__main__":
    main()
