"""Navigation: the batched strapdown mechanization (:mod:`~navsim.navigation.strapdown`), its
compiled block kernels (:mod:`~navsim.navigation.kernels`), the online magnetometer calibration
(:mod:`~navsim.navigation.magcal`) and the estimators (:mod:`~navsim.navigation.estimators`).

Arrays carry the run axis first: a state is ``(B, n)``, a covariance ``(B, n, n)``; an estimator
sees the sensors' measurements only, never the truth.
"""
