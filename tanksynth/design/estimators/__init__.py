"""The ``estimators`` family (design): state estimators (``kalman``, ``ekf``, ``ukf``,
``adaptive_kalman``, ``adaptive_scaling_kalman``, ``consensus_filter``, ``luenberger``,
``narx``).
"""

__all__: list[str] = []
