"""Database sinks of the twin (docs/plant.md, "Sinks")."""
