"""What runs in the loop and gets exported: estimators and control laws."""

from __future__ import annotations

__all__: list[str] = []
