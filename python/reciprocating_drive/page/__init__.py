"""The twin's live page (docs/page.md): `PageServer`, a sink that serves what the twin computes."""

from .server import PageError, PageServer

__all__ = ["PageError", "PageServer"]
