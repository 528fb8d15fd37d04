"""The closed loop (workflow layer, docs/closed-loop.md, docs/architecture.md): `system` builds and
runs the SSP system of the pump and the DriveTrain FMU (co-simulation, fmpy or libcosim),
`me_loop` is the Model Exchange master that solves the loop exactly.
"""
