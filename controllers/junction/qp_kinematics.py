"""Arrival times of a train planned in ``E = v²`` over distance, with their gradients as sparse rows (``qp_order``).

:mod:`.qp` plans each train's kinetic energy per unit mass ``E_j = v_j²`` at the breakpoints ``bp_j`` of its
distance grid; inside a segment the acceleration is constant, so ``E`` is linear in distance and the time to run
a segment is ``2ℓ/(√E_j + √E_{j+1})``. The QP's variables are the ``E_j`` and, for every breakpoint, its arrival
time ``t_j`` (tied to ``E`` by the linearised segment times, :meth:`Kinematics.segment_rows`). The time at any
position ``y`` is then *local*: ``t_j`` of its segment's start plus the run inside the segment — a row with three
entries (``E_j``, ``E_{j+1}``, ``t_j``), however far along the path ``y`` lies. That keeps every constraint row of
the QP short and the QP sparse and well conditioned.

:meth:`Kinematics.local` evaluates many positions at once and returns them as a :class:`Local`: the values
(time, ``E`` there) and the three coefficients of each row, never a dense matrix. :class:`Rows` collects
constraint rows from such pieces (``c(z) ≥ 0`` values plus their Jacobian as COO triplets); :class:`Queries`
batches the positions asked of each train so a train is evaluated once per phase, not once per constraint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Local:
    """Positions evaluated on one train's profile: per position its time and ``E``, and their linearisations.

    ``t ≈ t̄ + dE0·(E_j − Ē_j) + dE1·(E_{j+1} − Ē_{j+1}) + (t_{tcol} − t̄_{tcol})`` and
    ``E(y) = w0·E_j + w1·E_{j+1}``, with ``j`` the segment of each position (indices into the train's own grid).
    """

    t: np.ndarray
    E: np.ndarray
    j: np.ndarray
    dE0: np.ndarray
    dE1: np.ndarray
    tcol: np.ndarray
    w0: np.ndarray
    w1: np.ndarray

    def take(self, sl: slice) -> Local:
        return Local(
            self.t[sl], self.E[sl], self.j[sl], self.dE0[sl], self.dE1[sl], self.tcol[sl], self.w0[sl], self.w1[sl]
        )


class Kinematics:
    """One train's motion for ``E = v²`` at breakpoints ``bp``: arrival times at any positions and their gradients.

    Inside a segment the acceleration is constant (``v²`` linear in distance); beyond the last breakpoint the train
    holds its speed; positions before the first breakpoint are clamped to it.
    """

    def __init__(self, bp: np.ndarray, E: np.ndarray) -> None:
        self.bp, self.E = bp, E
        self.v = v = np.sqrt(E)
        self.ell = ell = np.diff(bp)
        vs = v[:-1] + v[1:]
        self.t_bp = np.concatenate([[0.0], np.cumsum(2.0 * ell / vs)])

    def segment_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Linearised segment times: ``t_{j+1} − t_j ≈ Δt̄_j + α_j (E_j − Ē_j) + β_j (E_{j+1} − Ē_{j+1})``."""
        vs = self.v[:-1] + self.v[1:]
        g = -2.0 * self.ell / vs**2
        return 2.0 * self.ell / vs, g / (2.0 * self.v[:-1]), g / (2.0 * self.v[1:])

    def local(self, ys: np.ndarray) -> Local:
        """Times and ``E`` at positions ``ys`` with their local (three-entry) linearisations."""
        bp, E, v, ell = self.bp, self.E, self.v, self.ell
        nb = bp.size
        ys = np.clip(np.atleast_1d(np.asarray(ys, dtype=float)), bp[0], None)
        beyond = ys >= bp[-1]
        j = np.clip(np.searchsorted(bp, ys, side="right") - 1, 0, nb - 2)
        d = np.where(beyond, 0.0, ys - bp[j])
        w = d / ell[j]
        ey = (1.0 - w) * E[j] + w * E[j + 1]
        vy = np.sqrt(np.maximum(ey, 1e-9))
        t = self.t_bp[j] + 2.0 * d / (v[j] + vy)
        h = -2.0 * d / (v[j] + vy) ** 2
        dE0 = h * (1.0 / (2.0 * v[j]) + (1.0 - w) / (2.0 * vy))
        dE1 = h * w / (2.0 * vy)
        tcol = j.copy()
        w0, w1 = 1.0 - w, w
        if np.any(beyond):  # held speed past the last breakpoint: t = t_last + (y − bp_last)/v_last
            db = ys[beyond] - bp[-1]
            t[beyond] = self.t_bp[-1] + db / v[-1]
            dE0[beyond] = 0.0
            dE1[beyond] = -db / (2.0 * E[-1] ** 1.5)
            tcol[beyond] = nb - 1
            ey[beyond] = E[-1]
            w0 = np.where(beyond, 0.0, w0)
            w1 = np.where(beyond, 1.0, w1)
        return Local(t, ey, j, dE0, dE1, tcol, w0, w1)

    def at(self, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`local` as dense rows × len(bp): ``(t, dt/dt_bp, dt/dE, E(y), dE(y)/dE)`` (tests, inspection)."""
        loc = self.local(ys)
        nb, rows = self.bp.size, np.arange(loc.t.size)
        Jt, JE, W = np.zeros((rows.size, nb)), np.zeros((rows.size, nb)), np.zeros((rows.size, nb))
        Jt[rows, loc.tcol] = 1.0
        np.add.at(JE, (rows, loc.j), loc.dE0)
        np.add.at(JE, (rows, loc.j + 1), loc.dE1)
        np.add.at(W, (rows, loc.j), loc.w0)
        np.add.at(W, (rows, loc.j + 1), loc.w1)
        return loc.t, Jt, JE, loc.E, W

    def position_at(self, ts: np.ndarray) -> np.ndarray:
        """Positions at times ``ts`` (the inverse of :meth:`local`; exact: constant acceleration in a segment)."""
        bp, E, v, ell = self.bp, self.E, self.v, self.ell
        ts = np.clip(np.atleast_1d(np.asarray(ts, dtype=float)), 0.0, None)
        j = np.clip(np.searchsorted(self.t_bp, ts, side="right") - 1, 0, bp.size - 2)
        tau = ts - self.t_bp[j]
        a = (E[j + 1] - E[j]) / (2.0 * ell[j])
        s = np.minimum(bp[j] + v[j] * tau + 0.5 * a * tau * tau, bp[j + 1])
        beyond = ts >= self.t_bp[-1]
        return np.where(beyond, bp[-1] + v[-1] * (ts - self.t_bp[-1]), s)


Term = tuple[np.ndarray, np.ndarray]  # (columns, coefficients): one entry per constraint row


def time_terms(loc: Local, e_off: int, t_off: int, scale: np.ndarray | float = 1.0) -> list[Term]:
    """The linearised time of ``loc`` as row entries over ``[E…, t…]`` (the train's blocks start at the offsets)."""
    one = np.ones(loc.t.size)
    return [(e_off + loc.j, scale * loc.dE0), (e_off + loc.j + 1, scale * loc.dE1), (t_off + loc.tcol, scale * one)]


def energy_terms(loc: Local, e_off: int, scale: np.ndarray | float = 1.0) -> list[Term]:
    """``E`` at the positions of ``loc`` (linear in the breakpoint ``E``) as row entries."""
    return [(e_off + loc.j, scale * loc.w0), (e_off + loc.j + 1, scale * loc.w1)]


def negated(terms: list[Term]) -> list[Term]:
    return [(c, -v) for c, v in terms]


class Rows:
    """Soft constraint rows ``c(z) ≥ 0``: values, kinds, and the Jacobian as COO triplets (duplicates add up)."""

    def __init__(self) -> None:
        self.values: list[np.ndarray] = []
        self.kinds: list[str] = []
        self._r: list[np.ndarray] = []
        self._c: list[np.ndarray] = []
        self._v: list[np.ndarray] = []
        self.m = 0

    def add(self, kind: str, values: np.ndarray | float, terms: list[Term]) -> None:
        vals = np.atleast_1d(np.asarray(values, dtype=float))
        rows = self.m + np.arange(vals.size)
        for cols, coef in terms:  # one entry per row (a term's arrays have the rows' length)
            self._r.append(rows)
            self._c.append(cols)
            self._v.append(coef)
        self.values.append(vals)
        self.kinds += [kind] * vals.size
        self.m += vals.size

    def done(self) -> tuple[np.ndarray, Jacobian, list[str]]:
        c = np.concatenate(self.values) if self.values else np.zeros(0)
        if self._r:
            jac = Jacobian(np.concatenate(self._r), np.concatenate(self._c), np.concatenate(self._v), self.m)
        else:
            jac = Jacobian(np.zeros(0, int), np.zeros(0, int), np.zeros(0), 0)
        return c, jac, self.kinds


@dataclass(frozen=True)
class Jacobian:
    """A sparse ``m × N`` matrix as COO triplets (repeated entries add up), with the product the SCP needs."""

    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    m: int

    def dot(self, x: np.ndarray) -> np.ndarray:
        return np.bincount(self.rows, weights=self.vals * x[self.cols], minlength=self.m)


class Queries:
    """Positions asked of each train, evaluated in one :meth:`Kinematics.local` call per train (:meth:`run`)."""

    def __init__(self, kin: list[Kinematics]) -> None:
        self.kin = kin
        self._ys: list[list[np.ndarray]] = [[] for _ in kin]
        self._n = [0] * len(kin)
        self._out: list[Local | None] = [None] * len(kin)

    def ask(self, k: int, ys: np.ndarray | float) -> tuple[int, slice]:
        ys = np.atleast_1d(np.asarray(ys, dtype=float))
        start = self._n[k]
        self._ys[k].append(ys)
        self._n[k] += ys.size
        return k, slice(start, start + ys.size)

    def run(self) -> None:
        for k, parts in enumerate(self._ys):
            if parts:
                self._out[k] = self.kin[k].local(np.concatenate(parts))

    def __getitem__(self, handle: tuple[int, slice]) -> Local:
        k, sl = handle
        out = self._out[k]
        assert out is not None, "Queries.run() first"
        return out.take(sl)
