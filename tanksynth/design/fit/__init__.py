"""The ``fit`` family (design): grey-box estimation of plant parameters from logged experiments.

`tanksynth.design.fit.estimation.fit_parameters` (arrays in, `FitResult` out),
`tanksynth.design.fit.validation` (validation runs and predicted outputs), and the adapter of
the ``fit`` method (`tanksynth.design.fit.adapters`).
"""

__all__: list[str] = []
