"""Sampling the touchdown conditions of a study.

Owns the seeded scrambled Sobol sequence (or pseudo-random numbers) in the unit
cube. It must not know a study, the scene or the step: the study maps the points
to its ranges (:func:`symcushion.envelope.study.sample_conditions`).
"""
from __future__ import annotations

import numpy as np

__all__ = ["MAX_SOBOL_DIMENSIONS", "SOBOL_BITS", "sobol", "sample_unit"]

#: Bits of the Sobol digits: 2^31 points per dimension before it repeats.
SOBOL_BITS = 31
# Joe & Kuo (2008) primitive polynomials and initial direction numbers
# (new-joe-kuo-6.21201), dimensions 2..13: (degree s, coefficients a, m_1..m_s).
_JOE_KUO = (
    (1, 0, (1,)), (2, 1, (1, 3)), (3, 1, (1, 3, 1)), (3, 2, (1, 1, 1)),
    (4, 1, (1, 1, 3, 3)), (4, 4, (1, 3, 5, 13)), (5, 2, (1, 1, 5, 5, 17)),
    (5, 4, (1, 1, 5, 5, 5)), (5, 7, (1, 1, 7, 11, 19)), (5, 11, (1, 1, 5, 1, 1)),
    (5, 13, (1, 1, 1, 3, 11)), (5, 14, (1, 3, 5, 5, 31)))
#: Dimensions of the built-in table (the first is van der Corput's).
MAX_SOBOL_DIMENSIONS = len(_JOE_KUO) + 1


def _direction_numbers(dim: int) -> np.ndarray:
    """Sobol direction numbers v_k (k = 1..SOBOL_BITS) as integers, one row per dimension."""
    if dim > len(_JOE_KUO) + 1:
        raise ValueError(f"`dim` = {dim}: the built-in Sobol table has {len(_JOE_KUO) + 1} "
                         "dimensions; use method = \"random\".")
    bits = SOBOL_BITS
    v = np.zeros((dim, bits), dtype=np.int64)
    for d in range(dim):
        if d == 0:
            m = [1] * bits                      # van der Corput: m_k = 1
        else:
            s, a, m0 = _JOE_KUO[d - 1]
            m = list(m0)
            for k in range(s, bits):            # m_k = 2a₁m_{k−1} ⊕ … ⊕ 2^s m_{k−s} ⊕ m_{k−s}
                new = m[k - s] ^ (m[k - s] << s)
                for i in range(1, s):
                    if (a >> (s - 1 - i)) & 1:
                        new ^= m[k - i] << i
                m.append(new)
        for k in range(bits):
            v[d, k] = m[k] << (bits - 1 - k)
    return v


def _parity(x: np.ndarray) -> np.ndarray:
    x = x.copy()
    for shift in (32, 16, 8, 4, 2, 1):
        x ^= x >> shift
    return x & 1


def sobol(n: int, dim: int, seed: int | None = 0, scramble: bool = True) -> np.ndarray:
    """Points of the Sobol sequence in [0, 1)^dim, optionally scrambled.

    Scrambling is Matoušek's linear matrix scramble plus a random digital
    shift (the scheme of SciPy's ``qmc.Sobol``): each dimension's direction
    numbers are multiplied by a random lower-triangular unit matrix over
    GF(2), then every point is XOR-ed with a random digit vector. Both keep
    the net property: the first 2^m points put exactly one point in each of
    the 2^m equal intervals of every coordinate. Points are the centres of
    their 2^−31 cells, never exactly 0 or 1.

    Parameters
    ----------
    n : int
        Number of points (balance is best when n is a power of two).
    dim : int
        Dimensions, ≤ 13.
    seed : int or None
        Seed of the scramble (NumPy ``default_rng``); ignored without scrambling.

    Returns
    -------
    ndarray, shape (n, dim)

    References
    ----------
    S. Joe, F. Y. Kuo (2008), Constructing Sobol sequences with better
    two-dimensional projections, SIAM J. Sci. Comput. 30, 2635–2654.
    J. Matoušek (1998), On the L2-discrepancy for anchored boxes, J. Complexity 14.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"`n` must be a non-negative integer, got {n!r}.")
    if n > 2 ** SOBOL_BITS:
        raise ValueError(f"`n` = {n} exceeds the 2^{SOBOL_BITS} points of the sequence.")
    bits = SOBOL_BITS
    v = _direction_numbers(dim)
    shift = np.zeros(dim, dtype=np.int64)
    if scramble and dim:
        rng = np.random.default_rng(seed)
        # lower-triangular unit matrix L: output bit r (MSB first) = input bit r ⊕ a
        # random combination of the more significant input bits
        for d in range(dim):
            rows = []
            for r in range(bits):
                above = int(rng.integers(0, 2 ** r)) if r else 0
                rows.append((above << (bits - r)) | (1 << (bits - 1 - r)))
            rows = np.array(rows, dtype=np.int64)
            scr = np.zeros(bits, dtype=np.int64)
            for r in range(bits):
                scr |= _parity(v[d][None, :] & rows[r]).ravel() << (bits - 1 - r)
            v[d] = scr
        shift = rng.integers(0, 2 ** bits, size=dim, dtype=np.int64)
    index = np.arange(n, dtype=np.int64)
    points = np.zeros((n, dim), dtype=np.int64)
    for k in range(max(1, int(n - 1).bit_length()) if n > 1 else 0):
        on = ((index >> k) & 1).astype(bool)
        points[on] ^= v[:, k]
    points ^= shift
    return (points.astype(np.float64) + 0.5) / 2.0 ** bits


def sample_unit(method: str, n: int, dim: int, seed: int) -> np.ndarray:
    """Uniform numbers in (0, 1), shape (n, dim): the scrambled Sobol' points of
    :func:`sobol` for ``method = "sobol"``, else NumPy's generator of ``seed``."""
    if method == "sobol":
        return sobol(n, dim, seed=seed)
    return np.random.default_rng(seed).random((n, dim))
