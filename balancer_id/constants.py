"""Physical constants and sensor facts shared by every stage (MODEL.md, paper Table IV)."""

from __future__ import annotations

#: Standard gravity used by the paper (m/s^2); every command takes ``--g`` to change it.
G_DEFAULT = 9.8

#: Sensor range and resolution of the PASCO wireless force/acceleration sensor (Table IV).
FORCE_RANGE_N = 50.0
FORCE_RESOLUTION_N = 0.03
ACCEL_RANGE_G = 16.0
ACCEL_RESOLUTION = 0.2
NOMINAL_RATE_HZ = 200.0

#: Karnopp zero-velocity band half-width (m/s), paper eq. (5).
KARNOPP_EPS = 1e-6
