"""Multiplexed codes (the paper's Fig. 9): S-matrix codes and their demultiplexing.

An S-matrix of order K is a K×K 0/1 matrix with (K+1)/2 ones per row whose inverse is
``2/(K+1) · (2 Sᵀ − J)``. It exists when a Hadamard matrix of order K+1 does, so only for
K ≡ 3 (mod 4). Row r of S is the shutter pattern of tile pixel r (raster order): each
pixel is open in about half the slots, so it gathers (K+1)/2 times the light of an
identity code.

**Demultiplexing** treats a tile as one super-pixel: ``v = S⁻¹ c`` recovers the tile's K
slot values from its K measurements, assuming the scene is constant over the tile (the
same assumption as the [K, 1/K] re-binning). The slot values are then placed at the
pixels an identity *placement order* fires in those slots, giving an identity-code
capture that every reconstruction accepts.

**Noise** (relative to an identity code): with read noise dominant the SNR gain is
(K+1)/(2√K) (2.07 at K=15); with photon noise dominant it becomes a loss, ≈0.73 at K=15,
because each measurement also carries the noise of the extra light. The real gain is
light throughput, (K+1)/(2K) of the exposure instead of 1/K.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flexvox_core.tiles import validate_tile


def _is_prime(q: int) -> bool:
    return q >= 2 and all(q % p for p in range(2, int(q**0.5) + 1))


def _jacobsthal(q: int) -> np.ndarray:
    """Q[i, j] = χ(j − i) for a prime q (χ the quadratic character mod q)."""
    squares = {(x * x) % q for x in range(1, q)}
    chi = np.array([0] + [1 if r in squares else -1 for r in range(1, q)])
    i, j = np.indices((q, q))
    return chi[(j - i) % q]


def hadamard(order: int) -> np.ndarray | None:
    """A Hadamard matrix (±1, H Hᵀ = order·I), or None when no construction here applies.

    Constructions: Sylvester (powers of 2), Paley I (order q+1, q prime ≡ 3 mod 4),
    Paley II (order 2(q+1), q prime ≡ 1 mod 4), and doubling (H ⊗ [[1, 1], [1, −1]]).
    """
    if order == 1:
        return np.ones((1, 1), dtype=np.int64)
    if order == 2:
        return np.array([[1, 1], [1, -1]], dtype=np.int64)
    if order % 4:
        return None
    h2 = np.array([[1, 1], [1, -1]], dtype=np.int64)
    q = order - 1
    if _is_prime(q) and q % 4 == 3:  # Paley I
        S = np.zeros((order, order), dtype=np.int64)
        S[0, 1:] = 1
        S[1:, 0] = -1
        S[1:, 1:] = _jacobsthal(q)
        return S + np.eye(order, dtype=np.int64)
    q = order // 2 - 1
    if _is_prime(q) and q % 4 == 1:  # Paley II
        C = np.zeros((q + 1, q + 1), dtype=np.int64)
        C[0, 1:] = 1
        C[1:, 0] = 1
        C[1:, 1:] = _jacobsthal(q)
        zero = np.array([[1, -1], [-1, -1]], dtype=np.int64)
        return np.kron(C, h2) + np.kron(np.eye(q + 1, dtype=np.int64), zero)
    half = hadamard(order // 2)
    return None if half is None else np.kron(half, h2)


def s_matrix(K: int) -> np.ndarray:
    """The S-matrix of order K (uint8 0/1, K×K).

    Raises
    ------
    ValueError
        For K not ≡ 3 (mod 4) (no S-matrix exists), or for a K whose Hadamard matrix of
        order K+1 none of the constructions here builds.

    Examples
    --------
    >>> s_matrix(3).tolist()
    [[1, 1, 0], [0, 1, 1], [1, 0, 1]]
    """
    if isinstance(K, bool) or not isinstance(K, int | np.integer) or K < 1:
        raise ValueError(f"`K` must be a positive whole number; got {K!r}")
    if K % 4 != 3:
        raise ValueError(
            f"no S-matrix exists for K = {K}: S-matrices need K = 3 (mod 4) (3, 7, 11, 15, ...), "
            "because they come from Hadamard matrices of order K+1, a multiple of 4"
        )
    H = hadamard(K + 1)
    if H is None:
        raise ValueError(
            f"no construction here builds a Hadamard matrix of order {K + 1} for an S-matrix of K = {K}"
        )
    H = H * H[0][None, :]  # normalise: first row +1
    H = H * H[:, :1]  # first column +1
    return ((1 - H[1:, 1:]) // 2).astype(np.uint8)


def noise_gains(S: np.ndarray) -> tuple[float, float]:
    """SNR gain of demultiplexed estimates over single-slot samples: (read, photon) noise.

    Read noise: every measurement has the same variance. Photon noise: a measurement's
    variance grows with the number of open slots (a uniform scene).
    """
    S = np.asarray(S, dtype=np.float64)
    D = np.linalg.inv(S)
    var_read = np.mean(np.sum(D**2, axis=1))
    var_photon = np.mean(D**2 @ S.sum(axis=1))
    return float(1 / np.sqrt(var_read)), float(1 / np.sqrt(var_photon))


@dataclass(frozen=True)
class MultiplexedCode:
    """An S-matrix code for one tile and the identity order its demultiplexed slots take.

    Attributes
    ----------
    tile : (int, int)
    S : ndarray, shape (K, K), uint8
        Row r is the shutter pattern of tile pixel r (raster order).
    code : ndarray, shape (m, n, K), bool
    demux : ndarray, shape (K, K), float64
        ``S⁻¹``: slot values of a tile = ``demux @ measurements``.
    placement : ndarray, shape (m, n), int
        Identity firing order whose pixels receive the demultiplexed slot values.
    snr_gain_read, snr_gain_photon : float
        See :func:`noise_gains`.
    throughput : float
        Fraction of the exposure each pixel is open, (K+1)/(2K).
    """

    tile: tuple[int, int]
    S: np.ndarray
    code: np.ndarray
    demux: np.ndarray
    placement: np.ndarray
    snr_gain_read: float
    snr_gain_photon: float
    throughput: float

    @property
    def K(self) -> int:  # noqa: N802
        """Slots per frame."""
        return self.tile[0] * self.tile[1]

    def __repr__(self) -> str:
        m, n = self.tile
        return (f"<MultiplexedCode tile {m}x{n} (K = {self.K}), throughput {self.throughput:.2f}, SNR gain "
                f"{self.snr_gain_read:.2f} under read noise, {self.snr_gain_photon:.2f} under photon noise>")

    def as_dict(self) -> dict:
        """JSON-ready form."""
        return {
            "tile": list(self.tile),
            "K": self.K,
            "multiplexed": True,
            "code": self.code.astype(int).tolist(),
            "placement_order": self.placement.tolist(),
            "snr_gain_read_noise": round(self.snr_gain_read, 4),
            "snr_gain_photon_noise": round(self.snr_gain_photon, 4),
            "throughput": round(self.throughput, 4),
        }


def multiplexed_code(tile, *, placement=None) -> MultiplexedCode:
    """Build the S-matrix code of a tile (K = m·n must be ≡ 3 mod 4).

    Parameters
    ----------
    tile : (int, int)
    placement : ndarray (m, n), optional
        Identity order that receives the demultiplexed slots; by default the one
        :func:`~flexvox_core.design.design_code` designs for the tile.
    """
    from flexvox_core.codes import validate_order
    from flexvox_core.design import design_code

    m, n = validate_tile(tile)
    K = m * n
    S = s_matrix(K)
    if placement is None:
        placement = design_code((m, n)).order
    placement = validate_order(placement)
    if placement.shape != (m, n):
        raise ValueError(f"`placement` must have shape ({m}, {n}); got {placement.shape}")
    code = S.astype(bool).reshape(m, n, K)
    demux = np.linalg.inv(S.astype(np.float64))
    read, photon = noise_gains(S)
    return MultiplexedCode((m, n), S, code, demux, placement, read, photon, (K + 1) / (2 * K))


def demultiplex(frames, mcode: MultiplexedCode) -> np.ndarray:
    """Turn a multiplexed capture ``(F, H, W)`` into an identity capture of ``mcode.placement``.

    Partial tiles at the right and bottom borders are completed by mirroring the image
    before demultiplexing (an approximation only those pixels see).
    """
    f = np.asarray(frames)
    if f.ndim != 3:
        raise ValueError(f"`frames` must have shape (F, H, W); got {f.ndim} dimensions {f.shape}")
    dtype = f.dtype if np.issubdtype(f.dtype, np.floating) else np.float32
    m, n = mcode.tile
    K = m * n
    F, H, W = f.shape
    Hp, Wp = -(-H // m) * m, -(-W // n) * n
    if (Hp, Wp) != (H, W):
        f = np.pad(f, ((0, 0), (0, Hp - H), (0, Wp - W)), mode="symmetric")
    tiles = f.reshape(F, Hp // m, m, Wp // n, n).transpose(0, 1, 3, 2, 4).reshape(F, Hp // m, Wp // n, K)
    slots = tiles.astype(np.float64) @ mcode.demux.T  # (F, ty, tx, K): slot values per tile
    placed = slots[..., mcode.placement.ravel()]  # pixel r gets the slot it fires in
    out = placed.reshape(F, Hp // m, Wp // n, m, n).transpose(0, 1, 3, 2, 4).reshape(F, Hp, Wp)
    return np.ascontiguousarray(out[:, :H, :W]).astype(dtype)
