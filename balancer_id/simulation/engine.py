"""Simulate a model for one trial or many (the public face of the kernel)."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from balancer_id.model.spec import Model
from balancer_id.simulation.inputs import Thrust
from balancer_id.simulation.kernel import OUT_COLUMNS, Kernel, get_kernel

if TYPE_CHECKING:
    import pandas as pd

#: Internal RK4 steps per sample interval.
DEFAULT_SUBSTEPS = 1


@dataclass
class Simulation:
    """The simulated signals of one trial at the requested sample times.

    Attributes
    ----------
    time : numpy.ndarray
        Sample times (s).
    accel : numpy.ndarray
        What the accelerometer sees after gravity removal (m/s^2), incl. ``output`` hooks.
    velocity, position : numpy.ndarray
        Load velocity (m/s) and position (m), up positive, zero at the start.
    drive_force : numpy.ndarray
        Drive force ``f`` after the lag (N).
    operating_force : numpy.ndarray
        Operating force ``h`` (N).
    """

    time: np.ndarray
    accel: np.ndarray
    velocity: np.ndarray
    position: np.ndarray
    drive_force: np.ndarray
    operating_force: np.ndarray

    def to_frame(self) -> pd.DataFrame:
        """The signals as a DataFrame indexed by time."""
        import pandas as pd

        return pd.DataFrame(
            {
                "accel": self.accel,
                "velocity": self.velocity,
                "position": self.position,
                "drive_force": self.drive_force,
                "operating_force": self.operating_force,
            },
            index=pd.Index(self.time, name="time"),
        )


@dataclass(frozen=True)
class TrialInput:
    """Everything that drives one simulated trial.

    Attributes
    ----------
    time : numpy.ndarray
        Output sample times (s); the state is ``x0`` at ``time[0]``.
    thrust : Thrust
        The operating thrust.
    z_ref, v_ref : numpy.ndarray or None
        A robot's reference position (m) and velocity (m/s) at ``time`` (``servo`` only).
    x0 : tuple of float or None
        The state at ``time[0]``: drive force ``f`` (N), velocity ``v`` (m/s) and position
        ``z`` (m); None is rest (all zero). A window that starts in motion (a session
        continued after a gap) starts from its estimated state.
    """

    time: np.ndarray
    thrust: Thrust
    z_ref: np.ndarray | None = None
    v_ref: np.ndarray | None = None
    x0: tuple[float, float, float] | None = None


def _param_vector(model: Model, params: Mapping[str, float] | Sequence[float]) -> np.ndarray:
    if isinstance(params, Mapping):
        return np.asarray(model.vector(params), dtype=float)
    vec = np.asarray(params, dtype=float)
    if vec.shape != (len(model.param_names),):
        raise ValueError(f"expected {len(model.param_names)} parameters {model.param_names}")
    return vec


def simulate(
    model: Model,
    params: Mapping[str, float] | Sequence[float],
    time: np.ndarray,
    thrust: Thrust,
    *,
    z_ref: np.ndarray | None = None,
    v_ref: np.ndarray | None = None,
    x0: tuple[float, float, float] | None = None,
    substeps: int = DEFAULT_SUBSTEPS,
) -> Simulation:
    """Simulate one trial of ``model``.

    Parameters
    ----------
    model : Model
        The model (see :func:`balancer_id.model.parse_model`).
    params : mapping or sequence
        Parameter values by name (missing ones take their defaults) or a vector in
        ``model.param_names`` order.
    time : numpy.ndarray
        Output sample times (s), increasing; the state is ``x0`` at ``time[0]``.
    thrust : Thrust
        The operating thrust (a step or a measured series).
    z_ref, v_ref : numpy.ndarray, optional
        A robot's reference position and velocity at ``time`` (for ``servo``).
    x0 : tuple of float, optional
        Drive force (N), velocity (m/s) and position (m) at ``time[0]``; None is rest.
    substeps : int
        RK4 steps per sample interval.

    Returns
    -------
    Simulation
    """
    out = simulate_many(
        model,
        params,
        [TrialInput(np.asarray(time, dtype=float), thrust, z_ref, v_ref, x0)],
        substeps=substeps,
    )
    return out[0]


@dataclass
class PackedTrials:
    """Trials packed into flat arrays for the batch kernel (built once per fit)."""

    t_all: np.ndarray
    offsets: np.ndarray
    bt_all: np.ndarray
    bu_all: np.ndarray
    boffsets: np.ndarray
    zr_all: np.ndarray
    vr_all: np.ndarray
    x0_all: np.ndarray

    @classmethod
    def pack(cls, trials: Sequence[TrialInput]) -> PackedTrials:
        """Concatenate the trials' arrays.

        Parameters
        ----------
        trials : sequence of TrialInput
            The trials, in order; a missing robot reference is packed as zeros.

        Returns
        -------
        PackedTrials
            Sample times, thrust breakpoints and values, and the robot references, each
            concatenated, with the offsets of each trial, and the initial states as an
            ``(n_trials, 3)`` array (rest where a trial has no ``x0``).
        """
        times = [np.ascontiguousarray(tr.time, dtype=float) for tr in trials]
        t_all = np.concatenate(times)
        if all(tr.z_ref is None and tr.v_ref is None for tr in trials):
            zr_all = vr_all = np.zeros_like(t_all)  # no robot: one array of zeros, read only
        else:
            zeros = [np.zeros_like(t) for t in times]
            zr_all = np.concatenate(
                [
                    z if tr.z_ref is None else np.asarray(tr.z_ref, float)
                    for z, tr in zip(zeros, trials, strict=True)
                ]
            )
            vr_all = np.concatenate(
                [
                    z if tr.v_ref is None else np.asarray(tr.v_ref, float)
                    for z, tr in zip(zeros, trials, strict=True)
                ]
            )
        return cls(
            t_all=t_all,
            offsets=np.concatenate([[0], np.cumsum([t.size for t in times])]).astype(np.int64),
            bt_all=_shared_if_equal(
                np.concatenate([tr.thrust.times for tr in trials], dtype=float), t_all
            ),
            bu_all=np.concatenate([tr.thrust.values for tr in trials], dtype=float),
            boffsets=np.concatenate(
                [[0], np.cumsum([tr.thrust.times.size for tr in trials])]
            ).astype(np.int64),
            zr_all=zr_all,
            vr_all=vr_all,
            x0_all=np.array(
                [(0.0, 0.0, 0.0) if tr.x0 is None else tr.x0 for tr in trials], dtype=float
            ).reshape(len(trials), 3),
        )

    def run(self, model: Model, pvec: np.ndarray, substeps: int = DEFAULT_SUBSTEPS) -> np.ndarray:
        """Simulate every trial; returns the ``(n_total, 5)`` output array.

        Parameters
        ----------
        model : Model
            The model; its kernel is compiled on first use.
        pvec : numpy.ndarray
            Parameter values in ``model.param_names`` order (SI units).
        substeps : int
            RK4 steps per sample interval.

        Returns
        -------
        numpy.ndarray
            One row per packed sample, columns :data:`OUT_COLUMNS`: acceleration
            (m/s^2), velocity (m/s), position (m), drive force (N), operating force (N).
        """
        out = np.empty((self.t_all.size, len(OUT_COLUMNS)))
        kernel = get_kernel(model)
        kernel.simulate_batch(
            self.t_all,
            self.offsets,
            self.bt_all,
            self.bu_all,
            self.boffsets,
            self.zr_all,
            self.vr_all,
            self.x0_all,
            kernel.parameters(pvec),
            substeps,
            out,
        )
        return out

    def run_sens(
        self,
        model: Model,
        pvec: np.ndarray,
        cols: Sequence[int],
        substeps: int = DEFAULT_SUBSTEPS,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Simulate every trial and the sensitivities of its output, in one pass.

        The forward sensitivities ``d state / d theta`` are integrated alongside the state
        with the same RK4 steps (the derivatives of the right-hand side are directional
        differences inside the kernel, so user hooks need no derivative code); the
        friction stick/slip events, the speed limit and the dead time's moving
        breakpoints change the sensitivities as they change the state.

        Parameters
        ----------
        model : Model
            The model; its kernel is compiled on first use.
        pvec : numpy.ndarray
            Parameter values in ``model.param_names`` order (SI units).
        cols : sequence of int
            What to differentiate with respect to: ``k < len(pvec)`` is parameter ``k``;
            ``len(pvec) + s`` (``s`` = 0, 1, 2) is the initial drive force, velocity or
            position of each trial (its column is then nonzero only in that trial's rows:
            the derivative of each trial's output with respect to its own ``x0[s]``).
        substeps : int
            RK4 steps per sample interval.

        Returns
        -------
        out : numpy.ndarray
            As :meth:`run`.
        sens : numpy.ndarray
            ``(n_total, len(cols))``: the derivative of the output acceleration (column 0
            of ``out``) with respect to each of ``cols``.
        """
        cols_arr = _sensitivity_columns(cols, pvec.size)
        pvec = np.ascontiguousarray(pvec, dtype=float)
        s_in = initial_sensitivities(self.offsets.size - 1, pvec.size, cols_arr)
        out, sens, _ = self._simulate_sens(model, pvec, cols_arr, substeps, s_in)
        return out, sens

    def sens_runner(
        self, model: Model, cols: Sequence[int], substeps: int = DEFAULT_SUBSTEPS
    ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """:meth:`run_sens` for many parameter vectors: the kernel, its columns and the
        output arrays prepared once (a sampler simulates the same trials tens of thousands
        of times; the preparation was a third of each call).

        Parameters
        ----------
        model : Model
            The model.
        cols : sequence of int
            What to differentiate with respect to (as :meth:`run_sens`).
        substeps : int
            RK4 steps per sample interval.

        Returns
        -------
        callable
            ``pvec`` to ``(out, sens)`` as :meth:`run_sens`; the arrays are reused by the
            next call (copy what must outlive it).
        """
        n_params = len(model.param_names)
        cols_arr = _sensitivity_columns(cols, n_params)
        s_in = initial_sensitivities(self.offsets.size - 1, n_params, cols_arr)
        out = np.empty((self.t_all.size, len(OUT_COLUMNS)))
        sens = np.empty((self.t_all.size, cols_arr.size))
        s_out = np.empty_like(s_in)
        kernel = get_kernel(model)
        kernel_cols = kernel.columns(cols_arr)

        def run(pvec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            self._sens_into(kernel, pvec, substeps, kernel_cols, out, sens, s_in, s_out)
            return out, sens

        return run

    def _sens_into(
        self,
        kernel: Kernel,
        pvec: np.ndarray,
        substeps: int,
        kernel_cols: np.ndarray,
        out: np.ndarray,
        sens: np.ndarray,
        s_in: np.ndarray,
        s_out: np.ndarray,
    ) -> None:
        """Run ``kernel``'s sensitivity kernel over the pack into ``out``, ``sens`` and
        ``s_out`` (``kernel_cols``: the columns in the kernel's own parameter places)."""
        kernel.simulate_batch_sens(
            self.t_all,
            self.offsets,
            self.bt_all,
            self.bu_all,
            self.boffsets,
            self.zr_all,
            self.vr_all,
            self.x0_all,
            kernel.parameters(pvec),
            substeps,
            kernel_cols,
            out,
            sens,
            s_in,
            s_out,
        )

    def _simulate_sens(
        self,
        model: Model,
        pvec: np.ndarray,
        cols: np.ndarray,
        substeps: int,
        s_in: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The sensitivity kernel from the sensitivities ``s_in`` (segments x 3 x cols);
        returns the output, the sensitivities and each segment's final ``S``."""
        out = np.empty((self.t_all.size, len(OUT_COLUMNS)))
        sens = np.empty((self.t_all.size, cols.size))
        s_out = np.empty_like(s_in)
        kernel = get_kernel(model)
        self._sens_into(kernel, pvec, substeps, kernel.columns(cols), out, sens, s_in, s_out)
        return out, sens, s_out

    def stream(
        self,
        model: Model,
        pvec: np.ndarray,
        max_rows: int,
        substeps: int = DEFAULT_SUBSTEPS,
    ) -> Iterator[tuple[int, np.ndarray]]:
        """Simulate every trial a block of rows at a time (a long log's memory bound).

        Parameters
        ----------
        model : Model
            The model.
        pvec : numpy.ndarray
            Parameter values in ``model.param_names`` order (SI units).
        max_rows : int
            Rows per block (at least 2); a trial longer than a block is split, the
            state running on across the split exactly as in one pass.
        substeps : int
            RK4 steps per sample interval.

        Yields
        ------
        first : int
            The block's first row.
        out : numpy.ndarray
            Its rows of :meth:`run`'s output.
        """
        carry: np.ndarray | None = None
        for block in self._blocks(max_rows):
            sub = block.pack(self, carry)
            out = sub.run(model, pvec, substeps)
            carry = out[-1, _STATE_COLUMNS] if block.split_after else None
            yield block.first, out[block.skip :]

    def stream_sens(
        self,
        model: Model,
        pvec: np.ndarray,
        cols: Sequence[int],
        max_rows: int,
        substeps: int = DEFAULT_SUBSTEPS,
    ) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        """:meth:`run_sens` a block of rows at a time; the sensitivities, like the state,
        run on across a split trial exactly as in one pass.

        Parameters
        ----------
        model : Model
            The model.
        pvec : numpy.ndarray
            Parameter values in ``model.param_names`` order (SI units).
        cols : sequence of int
            What to differentiate with respect to (see :meth:`run_sens`).
        max_rows : int
            Rows per block (at least 2).
        substeps : int
            RK4 steps per sample interval.

        Yields
        ------
        first : int
            The block's first row.
        out, sens : numpy.ndarray
            Its rows of :meth:`run_sens`'s output and sensitivities.
        """
        cols_arr = _sensitivity_columns(cols, pvec.size)
        pvec = np.ascontiguousarray(pvec, dtype=float)
        carry: np.ndarray | None = None
        carry_s: np.ndarray | None = None
        for block in self._blocks(max_rows):
            sub = block.pack(self, carry)
            s_in = initial_sensitivities(sub.offsets.size - 1, pvec.size, cols_arr)
            if carry_s is not None:
                s_in[0] = carry_s
            out, sens, s_out = sub._simulate_sens(model, pvec, cols_arr, substeps, s_in)
            carry = out[-1, _STATE_COLUMNS] if block.split_after else None
            carry_s = s_out[-1].copy() if block.split_after else None
            yield block.first, out[block.skip :], sens[block.skip :]

    def _blocks(self, max_rows: int) -> list[_Block]:
        """The row blocks of :meth:`stream` (each at most ``max_rows`` rows)."""
        n = int(self.t_all.size)
        size = max(2, int(max_rows))
        edges = set(self.offsets.tolist())  # a block edge here splits no segment
        return [
            _Block(a, min(n, a + size), a not in edges, min(n, a + size) not in edges)
            for a in range(0, n, size)
        ]


#: Output columns of the state (drive force, velocity, position), the order of ``x0``.
_STATE_COLUMNS = [3, 1, 2]

#: A split segment's breakpoints are kept from this long (s) before the block's first
#: sample on: enough for the drive's input delay (a dead time) to find the thrust that
#: acts there; a delay of a minute is no balancer's.
_BREAKPOINT_LOOKBACK_S = 60.0


@dataclass(frozen=True)
class _Block:
    """Rows ``[first, stop)`` of a pack; ``split_before``/``split_after``: a segment runs
    on across the block's first/last edge (then the block starts one row early, from the
    state the previous block ended in, and that row is skipped)."""

    first: int
    stop: int
    split_before: bool
    split_after: bool

    @property
    def skip(self) -> int:
        return 1 if self.split_before else 0

    def pack(self, whole: PackedTrials, carry: np.ndarray | None) -> PackedTrials:
        """The block's rows of ``whole`` as a pack of its own (views where it can)."""
        a = self.first - self.skip
        b = self.stop
        offs = whole.offsets
        j0 = int(np.searchsorted(offs, a, side="right")) - 1
        j1 = int(np.searchsorted(offs, b, side="left"))  # segments j0 .. j1-1
        edges = np.clip(offs[j0 : j1 + 1], a, b) - a
        b_lo, b_hi = [], []
        for j in range(j0, j1):
            lo, hi = int(whole.boffsets[j]), int(whole.boffsets[j + 1])
            if j == j0 and self.split_before:  # the thrust acting at the block's start on
                t0 = whole.t_all[a] - _BREAKPOINT_LOOKBACK_S
                lo += max(0, int(np.searchsorted(whole.bt_all[lo:hi], t0, side="right")) - 1)
            if j == j1 - 1 and self.split_after:  # none after the block's last sample
                last = whole.t_all[b - 1]
                hi = lo + int(np.searchsorted(whole.bt_all[lo:hi], last, side="right")) + 1
                hi = min(hi, int(whole.boffsets[j + 1]))
            b_lo.append(lo)
            b_hi.append(hi)
        bt = np.concatenate([whole.bt_all[lo:hi] for lo, hi in zip(b_lo, b_hi, strict=True)])
        bu = np.concatenate([whole.bu_all[lo:hi] for lo, hi in zip(b_lo, b_hi, strict=True)])
        sizes = np.array([hi - lo for lo, hi in zip(b_lo, b_hi, strict=True)], dtype=np.int64)
        x0 = whole.x0_all[j0:j1].copy()
        if self.split_before:
            assert carry is not None
            x0[0] = carry
        return PackedTrials(
            t_all=whole.t_all[a:b],
            offsets=edges.astype(np.int64),
            bt_all=bt,
            bu_all=bu,
            boffsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
            zr_all=whole.zr_all[a:b],
            vr_all=whole.vr_all[a:b],
            x0_all=x0,
        )


def _shared_if_equal(values: np.ndarray, other: np.ndarray) -> np.ndarray:
    """``other`` where it holds the same numbers as ``values`` (a measured thrust's
    breakpoints are the sample times: one array, not two, for the read-only kernel)."""
    return other if values.shape == other.shape and np.array_equal(values, other) else values


def _sensitivity_columns(cols: Sequence[int], n_params: int) -> np.ndarray:
    """``cols`` as the kernel's int64 array, checked against the parameter count."""
    cols_arr = np.ascontiguousarray(cols, dtype=np.int64).reshape(-1)
    if cols_arr.size and (cols_arr.min() < 0 or cols_arr.max() >= n_params + 3):
        raise ValueError(f"sensitivity columns must lie in 0..{n_params + 2}")
    return cols_arr


def initial_sensitivities(n_segments: int, n_params: int, cols: np.ndarray) -> np.ndarray:
    """The sensitivities ``S`` (segments x 3 x columns) at each segment's start.

    Zero for a parameter; the unit vector for an initial state (column
    ``n_params + s`` is the derivative with respect to state ``s`` of the segment's own
    ``x0``).

    Parameters
    ----------
    n_segments : int
        Segments packed.
    n_params : int
        Parameters of the model.
    cols : numpy.ndarray
        The sensitivity columns (see :meth:`PackedTrials.run_sens`).

    Returns
    -------
    numpy.ndarray
    """
    s_in = np.zeros((n_segments, 3, cols.size))
    for c, k in enumerate(cols):
        if k >= n_params:
            s_in[:, int(k) - n_params, c] = 1.0
    return s_in


def simulate_many(
    model: Model,
    params: Mapping[str, float] | Sequence[float],
    trials: Sequence[TrialInput],
    *,
    substeps: int = DEFAULT_SUBSTEPS,
) -> list[Simulation]:
    """Simulate several trials with the same parameters in one kernel call.

    Parameters
    ----------
    model : Model
        The model.
    params : mapping or sequence
        Parameter values (see :func:`simulate`).
    trials : sequence of TrialInput
        The trials.
    substeps : int
        RK4 steps per sample interval.

    Returns
    -------
    list of Simulation
    """
    for tr in trials:
        if tr.time.ndim != 1 or tr.time.size < 2 or np.any(np.diff(tr.time) <= 0):
            raise ValueError("simulation times must be a strictly increasing 1-D array")
    packed = PackedTrials.pack(trials)
    out = packed.run(model, _param_vector(model, params), substeps)
    sims = []
    for j in range(len(trials)):
        seg = out[packed.offsets[j] : packed.offsets[j + 1]]
        sims.append(
            Simulation(
                time=packed.t_all[packed.offsets[j] : packed.offsets[j + 1]],
                accel=seg[:, 0].copy(),
                velocity=seg[:, 1].copy(),
                position=seg[:, 2].copy(),
                drive_force=seg[:, 3].copy(),
                operating_force=seg[:, 4].copy(),
            )
        )
    return sims
