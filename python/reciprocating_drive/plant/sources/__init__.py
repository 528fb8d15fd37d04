"""Sources of the twin's samples (docs/plant.md, "Sources").

Layer: workflows, the plant (docs/architecture.md).
"""
