"""The ``decentralized`` family (verdicts and campaign runners): decentralised Kalman gains on a
sparsity pattern (``decentralized_kalman``).
"""

__all__: list[str] = []
