"""Every code example of README.md and docs/*.md runs as written (docs/README.md, "Code examples").

Each fenced ```python block runs as a script, each command of a ```sh block runs in bash, and each
```toml block (a design study) is loaded by the study reader, all in a scratch copy of the
repository's layout (scripts/, python/, data/, studies/, resources/, ssp/, the built FMUs under
target/, the venv as .venv) with a bounded timeout, so that relative paths such as
target/fmu/ReciprocatingDrive.fmu and results/ work as they do for a user and nothing is written into
the repository. A command passes when it exits with 0 and no traceback reaches its output.

A block that cannot run here (a Dask cluster, a Rust build, a benchmark) carries the visible marker
`<!-- not run: why -->` on the line before it, or `<!-- not run (commands 2-3): why -->` for some of
its commands; it is reported as skipped with that reason (`pytest -rs` lists them), never silently.
A command that must not run in a test (a build, a listening socket on all interfaces, a remote
address) and carries no marker fails instead of running.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import re
import shutil
import subprocess
import sys
import warnings
import xml.etree.ElementTree as ET

import pytest
from conftest import ROOT

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LANGUAGES = ("python", "sh", "toml")
TIMEOUT = 300  # s per example; the slowest (a 51-case sweep on a LocalCluster) takes about 5 s

MARKER = re.compile(r"<!--\s*not run(?:\s*\(commands?\s+([\d,\s-]+)\))?\s*:\s*(.+?)\s*-->")

# Commands that never run inside a test: they build Rust (minutes on a shared machine; the tests
# use the FMU that scripts/test.sh built), run the test suite itself, or reach beyond 127.0.0.1.
MUST_NOT_RUN = [
    (re.compile(r"\bcargo\b"), "builds Rust"),
    (re.compile(r"scripts/bench_\w+\.py"), "a benchmark: it builds, and measures for minutes"),
    (
        re.compile(r"scripts/(test|run|build-fmu|lint|fuzz|valgrind)\.sh"),
        "builds or runs the suite",
    ),
    (re.compile(r"tcp://(?!127\.0\.0\.1)|0\.0\.0\.0|\bdask (scheduler|worker)\b"), "a cluster"),
]


@dataclasses.dataclass
class Example:
    page: str  # relative to the repository
    line: int  # line of the block's opening fence
    language: str
    number: int  # the command's number in its block (1 for a whole python or toml block)
    code: str
    skip: str | None  # the reason it does not run here, or None

    @property
    def id(self) -> str:
        return f"{self.page}:{self.line}#{self.number}"


def _numbers(spec: str) -> set[int]:
    out = set()
    for part in spec.split(","):
        a, _, b = part.strip().partition("-")
        out.update(range(int(a), int(b or a) + 1))
    return out


def _commands(code: str) -> list[str]:
    """The commands of a shell block: continuation lines joined, comment lines dropped."""
    out, cur = [], ""
    for line in code.splitlines():
        if cur:
            cur += "\n" + line
        elif line.strip() and not line.lstrip().startswith("#"):
            cur = line
        else:
            continue
        if not line.endswith("\\"):
            out.append(cur)
            cur = ""
    if cur:
        out.append(cur)
    return out


def collect() -> list[Example]:
    out = []
    for page in PAGES:
        rel = page.relative_to(ROOT).as_posix()
        lines = page.read_text().splitlines()
        i = 0
        while i < len(lines):
            m = re.match(r"^```(\w*)\s*$", lines[i])
            if not m:
                i += 1
                continue
            start, lang = i, m.group(1)
            j = i + 1
            while not lines[j].startswith("```"):
                j += 1
            code = "\n".join(lines[start + 1 : j]) + "\n"
            prev = next((lines[k] for k in range(start - 1, -1, -1) if lines[k].strip()), "")
            mark = MARKER.search(prev)
            i = j + 1
            if lang not in LANGUAGES:
                OTHER_BLOCKS.append(f"{rel}:{start + 1} ({lang or 'no language'})")
                continue
            pieces = _commands(code) if lang == "sh" else [code]
            for n, piece in enumerate(pieces, 1):
                skip = None
                if mark and (mark.group(1) is None or n in _numbers(mark.group(1))):
                    skip = f"marked: {mark.group(2)}"
                out.append(Example(rel, start + 1, lang, n, piece, skip))
    return out


# Blocks in other languages (program output as `text`, C, XML): shown, not run; listed below.
OTHER_BLOCKS: list[str] = []
EXAMPLES = collect()


@pytest.fixture
def sandbox(tmp_path, fmu_path):
    """A scratch copy of the repository's layout, fresh for every example (no example sees the
    results of another, as on a user's fresh clone). scripts/ is copied (the scripts resolve the
    repository from their own path, so their default outputs land here); the rest is linked."""
    root = tmp_path / "repo"
    root.mkdir()
    shutil.copytree(ROOT / "scripts", root / "scripts")
    for d in ("python", "data", "studies", "resources", "ssp", "docs", "examples"):
        (root / d).symlink_to(ROOT / d)
    (root / ".venv").symlink_to(sys.prefix)
    fmus = root / "target" / "fmu"
    fmus.mkdir(parents=True)
    # The FMU under test, and its siblings (DriveTrain.fmu) from the same build.
    (fmus / "ReciprocatingDrive.fmu").symlink_to(pathlib.Path(fmu_path).resolve())
    for f in pathlib.Path(fmu_path).parent.glob("*.fmu"):
        if not (fmus / f.name).exists():
            (fmus / f.name).symlink_to(f.resolve())
    batch = ROOT / "target" / "release" / "libfmi2_batch.so"
    if batch.is_file():
        (root / "target" / "release").mkdir()
        (root / "target" / "release" / "libfmi2_batch.so").symlink_to(batch.resolve())
    return root


def _env(root: pathlib.Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT / "python")
    env["PATH"] = f"{root / '.venv' / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    env.pop("RD_FMU", None)  # the examples name their FMU themselves
    return env


def run(example: Example, root: pathlib.Path) -> subprocess.CompletedProcess:
    if example.language == "python":
        script = root / f"example_{example.line}.py"
        script.write_text(example.code)
        cmd = [sys.executable, str(script)]
    else:
        cmd = ["bash", "-c", example.code]
    return subprocess.run(
        cmd,
        cwd=root,
        env=_env(root),
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        stdin=subprocess.DEVNULL,
    )


@pytest.mark.parametrize("example", EXAMPLES, ids=[e.id for e in EXAMPLES])
def test_example_runs_as_written(example, sandbox):
    if example.skip:
        pytest.skip(f"{example.id} `{example.code.splitlines()[0][:60]}`: {example.skip}")
    if example.language == "toml":
        # A design study as docs/sweeps.md shows it: the study reader accepts it and builds cases.
        from reciprocating_drive.sweeps.study import load_study

        path = sandbox / f"study_{example.line}.toml"
        path.write_text(example.code)
        study = load_study(path, fmu=sandbox / "target" / "fmu" / "ReciprocatingDrive.fmu")
        assert study.n_cases > 0 and study.case(0), f"{example.id}: the study has no case"
        return
    if example.language == "sh":
        for pattern, why in MUST_NOT_RUN:
            assert not pattern.search(example.code), (
                f"{example.id}: `{example.code}` cannot run in a test ({why}); mark its block "
                "with <!-- not run: why --> on the line before"
            )
    r = run(example, sandbox)
    out = r.stdout + r.stderr
    assert r.returncode == 0 and "Traceback" not in out, (
        f"{example.id} exited with {r.returncode}:\n{example.code}\n{out[-3000:]}"
    )


def test_every_page_is_collected():
    """The collection sees the pages' blocks, and most of them run."""
    assert {e.page for e in EXAMPLES} >= {"README.md", "docs/user-guide.md", "docs/twin.md"}
    assert sum(not e.skip for e in EXAMPLES) >= 10
    # The list of what does not run, in the warnings summary of every run (pytest -q too).
    skipped = [e for e in EXAMPLES if e.skip]
    if skipped:
        warnings.warn(
            f"{len(skipped)} of {len(EXAMPLES)} code examples of the docs are not run here:\n"
            + "\n".join(
                f"  {e.id} `{e.code.splitlines()[0][:50].strip()}`: {e.skip}" for e in skipped
            )
            + f"\nand {len(OTHER_BLOCKS)} blocks in other languages: {', '.join(OTHER_BLOCKS)}",
            stacklevel=1,
        )


def _ssv_speed(name: str) -> float:
    """crank.speed of resources/presets/NAME.ssv, read with the standard XML parser."""
    root = ET.parse(ROOT / "resources" / "presets" / f"{name}.ssv").getroot()
    for p in root.iter():
        if p.tag.endswith("Parameter") and p.get("name") == "crank.speed":
            real = next(c for c in p if c.tag.endswith("Real"))
            return float(real.get("value"))
    raise KeyError(name)


def test_readme_presets_snippet_runs_the_presets_at_their_speeds(sandbox):
    """The README's "Presets" example keeps each preset's crank.speed: the FMU runs sk8-3.5-4000 at
    1.1414 rad/s and kvo630 at 157.08 rad/s (their .ssv files), not at the default 6.8068 rad/s."""
    text = (ROOT / "README.md").read_text().split("## Presets", 1)[1]
    block = next(e for e in EXAMPLES if e.page == "README.md" and e.code in text)
    r = run(block, sandbox)
    assert r.returncode == 0, r.stdout + r.stderr
    speeds = {}
    for line in r.stdout.splitlines():
        m = re.match(r"(\S+): crank\.model_speed ([-+\d.e]+) rad/s", line)
        if m:
            speeds[m.group(1)] = float(m.group(2))
    assert speeds.keys() == {"sk8-3.5-4000", "kvo630"}, r.stdout
    for name, speed in speeds.items():
        assert speed == _ssv_speed(name), (name, speed)
    # The speeds the README and the user guide quote, and not the default 65 strokes/min.
    assert round(speeds["sk8-3.5-4000"], 4) == 1.1414 and round(speeds["kvo630"], 2) == 157.08
