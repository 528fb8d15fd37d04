"""What every source of the twin's samples shares (workflow layer: the plant; docs/plant.md,
"Sources"): the error a source raises when it cannot go on. It lives below both the sources and the
pipeline that reports it, so that neither imports the other (docs/architecture.md).
"""


class SourceError(RuntimeError):
    """A source that cannot go on or refuses us (one line; never a secret)."""
