"""Database sinks of the twin (docs/plant.md, "Sinks").

Layer: workflows, the plant (docs/architecture.md).
"""
