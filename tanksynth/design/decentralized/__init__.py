"""The ``decentralized`` family (design): decentralised Kalman gains on a sparsity pattern
(``decentralized_kalman``).
"""

__all__: list[str] = []
