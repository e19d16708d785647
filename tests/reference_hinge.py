"""A plain scalar reference of the hinge-joint heading constraint (bpms.filter.hinge), written
from its documented steps 1–3 with lists and :mod:`math`, one frame and one hinge at a time:
slow and readable. The numba kernel must match it (tests/test_hinge_reference.py).

Per hinge (proximal p, distal d), every frame with both attitudes known:
1. the hinge axis in each sensor's axes, ``j_p``, ``j_d``: first Reset Zero's lateral axis
   ``Rᵀ C e_y``, then one power-iteration step per frame on ``prior·j₀j₀ᵀ + Σ r rᵀ dt``, with
   ``r = Q ω_d − ω_p`` (proximal axes, ``Q = R_pᵀ R_d``) and ``Qᵀ r`` (distal axes), taught
   only while the joint turns faster than ``min_rate`` and both segments are trusted
   (σ < clean); ``r`` is flipped to point along ``j_p``;
2. the relative heading ``δ`` between the horizontal parts of ``R_p j_p`` and ``R_d j_d``,
   weight ``w = |h_p| |h_d|``; ``δ̂ ← δ̂ + w k wrap(δ − δ̂)``, ``k = 1 − exp(−dt/τ)``;
3. each segment's heading uncertainty σ: while its magnetometer is flagged it moves towards
   the field's heading deviation ``dev`` by ``follow·dev·dt`` (never below where it was,
   never past ``dev`` by following), plus the gyro's drift ``drift·dt``; unflagged it decays
   by ``exp(−dt/recover)``. Both σ under ``clean``: δ̂ is the hinge's clean value δ̂₀ and no
   turn. Otherwise ``e = wrap(δ̂ − δ̂₀) / (σ_p² + σ_d² + floor²)``: the distal segment turns
   by ``e σ_d²``, the proximal by ``−e σ_p²`` about the world vertical (``Rz(ψ) R``).
"""

from __future__ import annotations

import math


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def _col(M, c: int) -> list[float]:
    return [M[0][c], M[1][c], M[2][c]]


def _t_mul_vec(M, v) -> list[float]:
    """Mᵀ v."""
    return [sum(M[r][a] * v[r] for r in range(3)) for a in range(3)]


def _mul_vec(M, v) -> list[float]:
    return [sum(M[a][c] * v[c] for c in range(3)) for a in range(3)]


def _turn(M, angle: float) -> list[list[float]]:
    """Rz(angle) · M (NED: about the vertical)."""
    c, s = math.cos(angle), math.sin(angle)
    return [[c * M[0][b] - s * M[1][b] for b in range(3)],
            [s * M[0][b] + c * M[1][b] for b in range(3)],
            [M[2][b] for b in range(3)]]


class _Hinge:
    def __init__(self) -> None:
        self.ready = False
        self.jp = self.jd = [0.0, 0.0, 0.0]
        self.mp = self.md = [[0.0] * 3 for _ in range(3)]
        self.offset = 0.0
        self.base = 0.0


def _teach(M, j, v, dt):
    for a in range(3):
        for b in range(3):
            M[a][b] += v[a] * v[b] * dt
    x = _mul_vec(M, j)
    n = math.sqrt(sum(c * c for c in x))
    return [c / n for c in x] if n > 0.0 else j


class ReferenceHinges:
    """The four hinges ``[(proximal, distal), ...]`` of 18 segments; settings as
    :class:`bpms.filter.hinge.HingeSettings` (degrees where it says so)."""

    def __init__(self, hinges, dt: float, tau_s=1.0, recover_s=5.0, follow_rate=1.2,
                 drift_dps=0.05, floor_deg=2.0, clean_deg=0.5, prior=2.0, min_rate=0.3):
        self.hinges = [tuple(h) for h in hinges]
        self.dt = dt
        self.k = 1.0 - math.exp(-dt / tau_s)
        self.decay = math.exp(-dt / recover_s) if recover_s > 0 else 0.0
        self.follow, self.drift = follow_rate, math.radians(drift_dps)
        self.floor, self.clean = math.radians(floor_deg), math.radians(clean_deg)
        self.prior, self.min_rate = prior, min_rate
        self.state = [_Hinge() for _ in self.hinges]
        self.sigma = [0.0] * 18

    def step(self, R, C, gyr, flag, heading_deg):
        """One frame: R, C ``[18][3][3]`` lists, gyr ``[18][3]``, flag ``[18]``, heading_deg
        ``[18]``; returns (turn ``[18]`` rad, R', C') with the turns applied."""
        dt = self.dt
        for i in range(18):
            if flag[i]:
                dev = abs(heading_deg[i]) * math.pi / 180.0 if math.isfinite(heading_deg[i]) \
                    else 0.0
                self.sigma[i] = min(self.sigma[i] + self.follow * dev * dt,
                                    max(self.sigma[i], dev)) + self.drift * dt
            else:
                self.sigma[i] *= self.decay
        turn = [0.0] * 18
        for (p, d), h in zip(self.hinges, self.state, strict=True):
            if not all(math.isfinite(x) for i in (p, d) for row in R[i] for x in row):
                continue
            if not h.ready:
                if not all(math.isfinite(C[i][a][1]) for i in (p, d) for a in range(3)):
                    continue
                h.jp = _t_mul_vec(R[p], _col(C[p], 1))
                h.jd = _t_mul_vec(R[d], _col(C[d], 1))
                h.mp = [[self.prior * h.jp[a] * h.jp[b] for b in range(3)] for a in range(3)]
                h.md = [[self.prior * h.jd[a] * h.jd[b] for b in range(3)] for a in range(3)]
                h.offset = h.base = 0.0
                h.ready = True
            Q = [[sum(R[p][r][a] * R[d][r][b] for r in range(3)) for b in range(3)]
                 for a in range(3)]
            rel = [x - y for x, y in zip(_mul_vec(Q, gyr[d]), gyr[p], strict=True)]
            if math.sqrt(sum(x * x for x in rel)) > self.min_rate:
                dist = _t_mul_vec(Q, rel)
                if sum(x * y for x, y in zip(rel, h.jp, strict=True)) < 0.0:
                    rel, dist = [-x for x in rel], [-x for x in dist]
                if self.sigma[p] < self.clean and self.sigma[d] < self.clean:
                    h.jp = _teach(h.mp, h.jp, rel, dt)
                    h.jd = _teach(h.md, h.jd, dist, dt)
            hp = _mul_vec(R[p], h.jp)[:2]
            hd = _mul_vec(R[d], h.jd)[:2]
            w = math.hypot(*hp) * math.hypot(*hd)
            if w > 1e-9:
                delta = math.atan2(hd[0] * hp[1] - hd[1] * hp[0], hd[0] * hp[0] + hd[1] * hp[1])
                h.offset += w * self.k * _wrap(delta - h.offset)
            if self.sigma[p] < self.clean and self.sigma[d] < self.clean:
                h.base = h.offset
                continue
            vp, vd = self.sigma[p] ** 2, self.sigma[d] ** 2
            e = _wrap(h.offset - h.base) / (vp + vd + self.floor ** 2)
            turn[d] += e * vd
            turn[p] -= e * vp
        R2 = [_turn(R[i], turn[i]) if turn[i] != 0.0 else R[i] for i in range(18)]
        C2 = [_turn(C[i], turn[i]) if turn[i] != 0.0 else C[i] for i in range(18)]
        return turn, R2, C2
