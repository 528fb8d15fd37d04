"""Copies the package's examples into a folder of your own, laid out as in the repository, so that
the commands of the README and of docs/ run there as written (docs/install.md "Examples"):

    rdrive examples DIR
    cd DIR
    rdrive twin data/twin/pump_encoder.csv --angle-unit counts --counts-per-rev 4096
    rdrive plant --config examples/twin/replay-sqlite.toml
    rdrive sweep studies/default_balancer.toml

DIR/data/twin/pump_encoder.csv   the twin's sample data (a 4096-count encoder at 1 kHz)
DIR/examples/twin/*.toml         plant configurations and alarm limits (paths relative to the file)
DIR/studies/*.toml               design studies

The configurations name their files relative to themselves, so they read DIR/data/ and write
DIR/results/. Results are written where you run the commands (results/ of the current folder),
never inside the installation. An existing file is not overwritten unless --force is given.
"""

# Layer: commands (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import pathlib
import shutil
import sys

from .. import artifacts
from ..cli_errors import EXIT_USAGE, ArgumentParser


def sources() -> list[tuple[pathlib.Path, str]]:
    """(file, path inside DIR) of everything copied: the repository's layout."""
    files = [(artifacts.twin_sample(), "data/twin/pump_encoder.csv")]
    files += [
        (p, f"examples/twin/{p.name}") for p in sorted(artifacts.examples_dir().glob("*.toml"))
    ]
    files += [(p, f"studies/{p.name}") for p in sorted(artifacts.studies_dir().glob("*.toml"))]
    return files


def main(argv=None, prog: str | None = None) -> int:
    prog = prog or "rdrive examples"
    ap = ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("dir", type=pathlib.Path, metavar="DIR", help="the folder to copy into")
    ap.add_argument("--force", action="store_true", help="overwrite files already there")
    a = ap.parse_args(argv)
    files = sources()
    missing = [str(src) for src, _ in files if not src.is_file()]
    if missing:
        print(f"{prog}: {missing[0]} is missing from this installation", file=sys.stderr)
        return EXIT_USAGE
    dest = a.dir.resolve()
    if artifacts.installed() and dest.is_relative_to(artifacts.PACKAGE):
        print(
            f"{prog}: {a.dir} is inside the installation ({artifacts.PACKAGE}); copy the "
            "examples into a folder of your own",
            file=sys.stderr,
        )
        return EXIT_USAGE
    if not a.force:
        there = [rel for _, rel in files if (dest / rel).exists()]
        if there:
            print(
                f"{prog}: {a.dir / there[0]} exists (and {len(there) - 1} more); "
                "--force overwrites them",
                file=sys.stderr,
            )
            return EXIT_USAGE
    try:
        for src, rel in files:
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dest / rel)
    except OSError as e:
        print(f"{prog}: {e.filename or a.dir}: {e.strerror or e}", file=sys.stderr)
        return EXIT_USAGE
    print(f"copied {len(files)} files into {a.dir}: data/twin/, examples/twin/, studies/")
    print(
        f"next: cd {a.dir} && rdrive twin data/twin/pump_encoder.csv --angle-unit counts --counts-per-rev 4096"
    )
    return 0
