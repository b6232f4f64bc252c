"""Compiled kernels (numba ``njit(cache=True)``): per-sample work over a block of IMU samples,
one module per concept.

Python is entered once per block of ``K`` samples, not once per IMU sample, and a run's
arithmetic never depends on the other runs (a batch of 3 equals 3 single runs bit for bit):
the Kalman kernels loop over the runs and, inside, over the samples; the strapdown
integrates tiles of 64 runs side by side in vector lanes, which round as scalar code does.

- :mod:`~navsim.navigation.kernels.earth`: the WGS-84 radii, gravity with J2 and its gradient
  at one point;
- :mod:`~navsim.navigation.kernels.strapdown`: the strapdown mechanization in the local-level
  NED frame (:func:`strapdown_block`, behind :class:`navsim.navigation.strapdown.BlockStrapdown`;
  its formulas in the module's docstring);
- :mod:`~navsim.navigation.kernels.dynamics`: the SINS error model's ``F``
  (:func:`error_dynamics`, with :func:`gravity_gradient`);
- :mod:`~navsim.navigation.kernels.covariance`: Kalman filter epochs, per run over the ``n``
  states: :func:`discretize_series` (the matrix-exponential series of ``Phi`` and ``Qd``),
  :func:`predict` (``Phi P Phi^T + Qd``), :func:`propagate_covariance`;
- :mod:`~navsim.navigation.kernels.update`: :func:`joseph_update` (the Joseph form in
  ``O(n^2 m)``) and the error-state feedback (:func:`feed_back`, :func:`rodrigues`);
- :mod:`~navsim.navigation.kernels.records`: a record's navigation errors, NEES and covariance
  checks (:func:`nav_errors`, :func:`covariance_codes`, :func:`covariance_record`);
- :mod:`~navsim.navigation.kernels.linalg`: the dense products and solve they share.

Products skip the zeros of their left factor (most of an error-state ``F``), and their
innermost loops run along rows so that LLVM vectorises them; the tests hold each to the same
formula written with numpy. The public kernels are importable from this package too.

The IMU's error processes are in :mod:`navsim.sensors.kernels`. The compiled code is cached in
``<navsim cache>/numba`` (:mod:`navsim.foundations.compiled`), or in ``$NUMBA_CACHE_DIR``.
"""

from navsim.navigation.kernels.covariance import discretize_series, predict, propagate_covariance
from navsim.navigation.kernels.dynamics import error_dynamics
from navsim.navigation.kernels.earth import gravity_gradient, radii
from navsim.navigation.kernels.records import covariance_codes, covariance_record, nav_errors
from navsim.navigation.kernels.strapdown import CACHE_SIZE, strapdown_block
from navsim.navigation.kernels.update import feed_back, joseph_update, rodrigues

__all__ = ["CACHE_SIZE", "covariance_codes", "covariance_record", "discretize_series", "error_dynamics", "feed_back",
           "gravity_gradient", "joseph_update", "nav_errors", "predict", "propagate_covariance", "radii", "rodrigues",
           "strapdown_block"]
