"""The twin's live page (docs/page.md): `PageServer`, a sink that serves what the twin computes.

Layer: workflows, the page (docs/architecture.md).
"""

from .server import PageError, PageServer

__all__ = ["PageError", "PageServer"]
