"""Reading logs: PASCO Capstone, PASCO SPARKvue, phyphox, Sensor Logger, Vernier, generic CSV.

Public entry points: :func:`read_log` (detects the layout and returns a :class:`Log`)
and :func:`write_log` (writes :class:`Recording` objects the way the programs do).

The pipeline, one module per step: :mod:`~balancer_id.read.sniff` (size, encoding, BOM,
delimiter, decimal mark, header) -> :mod:`~balancer_id.read.header` (column names into
quantity, unit, run, kind) -> the first layout of :data:`~balancer_id.read.layouts.LAYOUTS`
that claims the header (:mod:`~balancer_id.read.pasco`, :mod:`~balancer_id.read.phyphox`,
:mod:`~balancer_id.read.sensorlogger`, :mod:`~balancer_id.read.vernier`), else
:mod:`~balancer_id.read.generic` (which columns make which run:
:class:`~balancer_id.read.plan.RunPlan`) -> :mod:`~balancer_id.read.table`
(numbers, with pandas' C engine) -> :mod:`~balancer_id.read.assemble`,
:mod:`~balancer_id.read.units` and :mod:`~balancer_id.read.validate` (recordings, units,
time checks, gaps, saturation).

Decisions
---------
* Each run keeps the rows where its time and its force/acceleration are present; blank
  cells (padding of short runs, derived columns blank at the edges) drop out, nothing is
  interpolated. Force and acceleration at clearly different rates, under one time column
  (blank cells) or under time columns of their own, make one recording on the
  acceleration's sample times: the acceleration is never interpolated, the force is
  averaged (faster) or interpolated (slower) onto them (:mod:`~balancer_id.read.resample`),
  and a warning says so. Extra channels (gyro, position, velocity) are aligned with the
  run's rows and may hold NaN.
* Only regular files are read (FIFOs, devices, folders refused before any ``open``),
  streamed within a byte limit counted as read; a cut last line is dropped and infinite
  or absurd values are read as missing samples, each with a warning; a resting
  acceleration that contradicts the unit or ``g`` the user forced is refused.
* A single acceleration column (a motion sensor's ``Acceleration (m/s²)``, a generic
  ``a``) is returned with shape ``(n, 1)`` and axis label ``"z"`` (taken as vertical);
  it includes gravity when its median is beyond g/2 in size (a motion sensor's
  acceleration is kinematic, so it does not).
* phyphox ``Acceleration x`` includes g, ``Linear Acceleration x`` does not; bare
  ``X (m/s^2)`` (per-sensor files), PASCO and generic three-axis accelerations are judged
  from the data (median magnitude) unless the file is named ``Linear ...``.
* Units: ``(g)`` in the header is converted with ``g``; with ``accel_unit="auto"`` an
  acceleration that includes gravity and rests at a magnitude ~1 is taken to be in g,
  converted, and a warning says so; one beyond 25 is raw counts, refused with the column
  map that scales them. The time's unit comes from the column map, the layout, the
  header, the name or the values (:mod:`~balancer_id.read.timebase`); a clock time is
  counted from the first sample and its start kept (``Recording.started_at``).
* Runs named by the user (SPARKvue ``Force (N) 9.9``) keep that name; unnamed runs
  (phyphox, generic, a header without run suffix) are called ``"Run 1"``.
* Time going backwards or repeating is an error naming the line; a step longer than
  1.5 median steps is a :class:`Gap`.
"""

from __future__ import annotations

from balancer_id.read.reader import read_log
from balancer_id.read.recording import FORMATS, Gap, Log, Recording
from balancer_id.read.writers import write_log

__all__ = ["FORMATS", "Gap", "Log", "Recording", "read_log", "write_log"]
