#!/usr/bin/env python3
"""Coefficients of the exp polynomial of engine/src/simd/exp-inl.h (exp_lanes: the obstacle term and the contact force).

e^r on [-ln2/2, ln2/2] interpolated at the degree+1 Chebyshev nodes (within a small factor of
the minimax polynomial), in the monomial basis, rounded to double and printed as hex
literals, lowest power first, with the interpolant's largest relative error from e^r
(sampled; before rounding the coefficients and without the evaluation's own rounding).

    tools/exp_polynomial.py [degree]     (default 10)
"""
import sys
from decimal import Decimal, getcontext

getcontext().prec = 60


def cos(x):
    """cos(x) to the context's precision (Decimal has exp and ln, not cos)."""
    getcontext().prec += 2
    term, total, k = Decimal(1), Decimal(1), 0
    while True:
        k += 2
        term *= -x * x / (k * (k - 1))
        if total + term == total:
            break
        total += term
    getcontext().prec -= 2
    return +total


def pi():
    """pi by Machin's formula."""
    def atan_inv(n):
        getcontext().prec += 2
        x, total, k, sign = Decimal(1) / n, Decimal(0), 1, 1
        power = x
        while True:
            term = power / k
            if total + sign * term == total:
                break
            total += sign * term
            power *= x * x
            k += 2
            sign = -sign
        getcontext().prec -= 2
        return +total
    return 4 * (4 * atan_inv(5) - atan_inv(239))


def interpolant(degree):
    a = Decimal(2).ln() / 2
    count = degree + 1
    nodes = [a * cos(pi() * (2 * k + 1) / (2 * count)) for k in range(count)]
    # Newton's divided differences, then the Newton form expanded into powers of r
    newton = [x.exp() for x in nodes]
    for j in range(1, count):
        for i in range(count - 1, j - 1, -1):
            newton[i] = (newton[i] - newton[i - 1]) / (nodes[i] - nodes[i - j])
    poly = [Decimal(0)] * count
    for i in range(count - 1, -1, -1):
        shifted = [Decimal(0)] + poly[:-1]
        poly = [s - p * nodes[i] for s, p in zip(shifted, poly)]
        poly[0] += newton[i]
    worst = Decimal(0)
    for s in range(-2000, 2001):
        r = a * s / 2000
        value = Decimal(0)
        for c in reversed(poly):
            value = value * r + c
        worst = max(worst, abs(value / r.exp() - 1))
    return poly, worst


def main():
    degree = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    poly, worst = interpolant(degree)
    print(f"degree {degree}: largest relative error of the interpolant {float(worst):.2e}")
    for k, c in enumerate(poly):
        print(f"  r^{k}: {float(c).hex()}")


if __name__ == "__main__":
    main()
