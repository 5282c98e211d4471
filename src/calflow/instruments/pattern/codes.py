"""Binary maximum-length sequences (m-sequences) and the distances between their windows.

An m-sequence of order ``n`` is produced by a linear feedback shift register whose feedback
polynomial is primitive over GF(2); every non-zero ``n``-bit word appears exactly once in its
period of ``2**n - 1`` bits, so any ``n`` consecutive bits locate themselves (thesis Sec. 3.5.1,
step 9: "LFSR sequence reconstruction and decoding"). Reading more than ``n`` bits gives the
redundancy that lets the decoder check a reading instead of trusting it.

A polynomial is given by its exponents, highest first: ``(11, 2, 0)`` is ``x^11 + x^2 + 1``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

MAX_ORDER = 24


def _poly_int(exponents) -> int:
    return sum(1 << int(e) for e in exponents)


def _mulmod(a: int, b: int, mod: int, n: int) -> int:
    """a·b mod ``mod`` over GF(2); ``mod`` has degree ``n``."""
    out = 0
    while b:
        if b & 1:
            out ^= a
        b >>= 1
        a <<= 1
        if a >> n & 1:
            a ^= mod
    return out


def _powmod_x(e: int, mod: int, n: int) -> int:
    result, base = 1, 2  # the polynomials 1 and x
    while e:
        if e & 1:
            result = _mulmod(result, base, mod, n)
        base = _mulmod(base, base, mod, n)
        e >>= 1
    return result


def _prime_factors(m: int) -> list[int]:
    out, d = [], 2
    while d * d <= m:
        while m % d == 0:
            if d not in out:
                out.append(d)
            m //= d
        d += 1
    if m > 1:
        out.append(m)
    return out


def is_primitive(exponents) -> bool:
    """Whether the GF(2) polynomial with these exponents is primitive (its LFSR has period 2^n − 1)."""
    exponents = sorted({int(e) for e in exponents}, reverse=True)
    n = exponents[0]
    if n < 2 or exponents[-1] != 0:
        return False
    mod, order = _poly_int(exponents), (1 << n) - 1
    if _powmod_x(order, mod, n) != 1:
        return False
    return all(_powmod_x(order // q, mod, n) != 1 for q in _prime_factors(order))


def reciprocal(exponents) -> tuple[int, ...]:
    """The reciprocal polynomial x^n p(1/x): the one the reversed sequence satisfies."""
    n = max(exponents)
    return tuple(sorted((n - int(e) for e in exponents), reverse=True))


@lru_cache(maxsize=64)
def primitive_polynomials(n: int, count: int = 4) -> tuple[tuple[int, ...], ...]:
    """The first ``count`` primitive trinomials/pentanomials of order ``n``, by increasing value,
    leaving out self-reciprocal ones (a reversed reading must not pass for a forward one)."""
    if not 2 <= n <= MAX_ORDER:
        raise ValueError(f"code order {n}: expected 2 to {MAX_ORDER}")
    found: list[tuple[int, ...]] = []
    candidates = [(n, k, 0) for k in range(1, n)]
    candidates += [(n, a, b, c, 0) for a in range(3, n) for b in range(2, a) for c in range(1, b)]
    for poly in candidates:
        if is_primitive(poly) and reciprocal(poly) != poly:
            found.append(poly)
            if len(found) == count:
                break
    return tuple(found)


def lfsr_bits(exponents, length: int) -> np.ndarray:
    """The first ``length`` bits (uint8) of the m-sequence of this polynomial, seed all ones.

    The recurrence is s[k+n] = Σ_i c_i s[k+i] (mod 2) over the exponents i < n of the polynomial.
    """
    exponents = sorted({int(e) for e in exponents}, reverse=True)
    n = exponents[0]
    taps = [e for e in exponents[1:]]
    out = np.ones(max(length, n), dtype=np.uint8)
    for k in range(n, length):
        v = 0
        for e in taps:
            v ^= out[k - n + e]
        out[k] = v
    return out[:length]


def check_recurrence(bits: np.ndarray, exponents) -> int:
    """Index of the first bit that breaks the polynomial's recurrence, or −1 when none does."""
    exponents = sorted({int(e) for e in exponents}, reverse=True)
    n = exponents[0]
    bits = np.asarray(bits, dtype=np.uint8)
    if len(bits) <= n:
        return -1
    pred = np.zeros(len(bits) - n, dtype=np.uint8)
    for e in exponents[1:]:
        pred ^= bits[e : len(bits) - n + e]
    bad = np.flatnonzero(pred != bits[n:])
    return int(bad[0] + n) if len(bad) else -1


def window_distance(a: np.ndarray, b: np.ndarray, m: int, same: bool = False) -> int:
    """Smallest Hamming distance between a window of ``m`` bits of ``a`` and one of ``b``.

    With ``same`` (``b`` is ``a``), a window is not compared with itself. Computed along each
    diagonal of the window pairs with a running sum, O(len(a)·len(b)) small integer operations.
    """
    a = np.asarray(a, dtype=np.int8)
    b = np.asarray(b, dtype=np.int8)
    na, nb = len(a) - m + 1, len(b) - m + 1
    if na < 1 or nb < 1:
        return m
    best = m
    for shift in range(-(na - 1), nb):  # window i of a against window i + shift of b
        if same and shift == 0:
            continue
        i0 = max(0, -shift)
        i1 = min(na, nb - shift)
        if i1 <= i0:
            continue
        x = a[i0 : i1 + m - 1] != b[i0 + shift : i1 + shift + m - 1]
        c = np.concatenate(([0], np.cumsum(x, dtype=np.int32)))
        d = int((c[m:] - c[:-m]).min())
        if d < best:
            best = d
            if best == 0:
                break
    return best
