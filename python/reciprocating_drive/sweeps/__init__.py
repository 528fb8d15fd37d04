"""Design sweeps (workflow layer, docs/sweeps.md, docs/architecture.md): `study` reads and checks a
study file, `sweep` runs its cases on Dask and writes the results, `cases` runs a batch of cases
through the native batch library, `plots` draws the results.
"""
