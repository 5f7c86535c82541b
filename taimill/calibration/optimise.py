"""A bracketed 1-D minimiser: Brent's method (parabolic steps, golden-section fallback),
after R. P. Brent, "Algorithms for Minimization without Derivatives" (1973), ch. 5."""

from __future__ import annotations

import math

GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))  # 0.381966…


def brent(f, a: float, b: float, c: float, *, fb: float | None = None, xtol: float = 1e-5, maxiter: int = 60):
    """Minimise f on [a, c] given a bracket a < b < c with f(b) below f(a) and f(c).
    Returns (x, f(x), evaluations); stops when x is known to within ~2·xtol (absolute)."""
    x = w = v = b
    fx = fw = fv = f(b) if fb is None else fb
    calls = 0 if fb is not None else 1
    d = e = 0.0
    for _ in range(maxiter):
        m = 0.5 * (a + c)
        tol = xtol
        if abs(x - m) <= 2.0 * tol - 0.5 * (c - a):
            break
        parabolic = False
        if abs(e) > tol:  # fit a parabola through x, w, v
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0:
                p = -p
            q = abs(q)
            if abs(p) < abs(0.5 * q * e) and q * (a - x) < p < q * (c - x):  # inside, and shrinking
                e, d = d, p / q
                parabolic = True
                u = x + d
                if u - a < 2 * tol or c - u < 2 * tol:
                    d = tol if m > x else -tol
        if not parabolic:
            e = (c - x) if x < m else (a - x)
            d = GOLDEN * e
        u = x + (d if abs(d) >= tol else (tol if d > 0 else -tol))
        fu = f(u)
        calls += 1
        if fu <= fx:
            if u < x:
                c = x
            else:
                a = x
            v, w, x, fv, fw, fx = w, x, u, fw, fx, fu
        else:
            if u < x:
                a = u
            else:
                c = u
            if fu <= fw or w == x:
                v, w, fv, fw = w, u, fw, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
    return x, fx, calls
