"""Sources of the twin's samples (docs/plant.md, "Sources")."""
