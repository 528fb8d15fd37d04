"""The twin in a plant (docs/plant.md): samples from a source (a CSV file, an OPC UA server), the
twin's core (`reciprocating_drive.twin.Twin`), and database sinks that commit each checkpoint in the
same transaction as the rows it covers.

Layer: workflows, the plant (docs/architecture.md).
"""
