"""Report stage: LaTeX design reports (built by the reports issue)."""

__all__: list[str] = []
