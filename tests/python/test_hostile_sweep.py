"""The design sweeps under hostile input (issue "as hard to break as the FMU"; docs/sweeps.md
"Errors and exit codes"). Every case runs the real command, scripts/sweep.py, as a subprocess with a
bounded timeout, and checks the rules of the house:

* a user error exits 2 with exactly ONE line on stderr that names the file or option, the key and
  the value; nothing else is written (no result folder);
* no "Traceback" anywhere, whatever the input;
* no run that differs from a clean run ends with exit 0 (a stale result file is refused; every
  case rejected exits 1);
* every wait is bounded (a scheduler address where no Dask scheduler answers; Ctrl-C).

Property-based part (Hypothesis): malformed study files (one mutation of a valid study, or arbitrary
bytes) and malformed options. Validation happens before any cluster starts, which is what keeps a
generated case at about a second. Named part: the findings of the issue, one test each.
"""

from __future__ import annotations

import io
import json
import math
import os
import pathlib
import signal
import socket
import subprocess
import sys
import threading
import time
import zipfile

import pytest
from conftest import ROOT
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

SWEEP = ROOT / "scripts" / "sweep.py"
TIMEOUT = 120  # s, any single command
HYPOTHESIS = settings(
    max_examples=int(os.environ.get("RD_HOSTILE_EXAMPLES", "12")),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    derandomize=True,
)


def _default_sigint():
    # The test runner may run with SIGINT ignored (a background job); the command must see
    # Ctrl-C as a user's terminal delivers it.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run(args, timeout=TIMEOUT, **kw):
    p = subprocess.run(
        [sys.executable, str(SWEEP), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=_default_sigint,
        **kw,
    )
    assert "Traceback" not in p.stdout + p.stderr, p.stderr
    return p


def assert_user_error(p, *words, code=2):
    lines = p.stderr.strip().splitlines()
    assert p.returncode == code, (p.returncode, p.stderr)
    assert len(lines) == 1, p.stderr
    for w in words:
        assert str(w) in lines[0], (w, lines[0])
    return lines[0]


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return (
            "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
        )
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a TOML basic string: JSON's escapes are TOML's
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return (
            "{ "
            + ", ".join(
                f"{json.dumps(k, ensure_ascii=False)} = {toml_value(x)}" for k, x in v.items()
            )
            + " }"
        )
    raise TypeError(v)


def to_toml(doc: dict) -> str:
    """A small TOML writer for the generated studies (tomllib reads, nothing in the venv writes)."""
    out = [
        f"{json.dumps(k, ensure_ascii=False)} = {toml_value(v)}"
        for k, v in doc.items()
        if not isinstance(v, dict)
    ]
    for k, v in doc.items():
        if isinstance(v, dict):
            out.append(f"[{json.dumps(k, ensure_ascii=False)}]")
            out += [
                f"{json.dumps(kk, ensure_ascii=False)} = {toml_value(vv)}" for kk, vv in v.items()
            ]
    return "\n".join(out) + "\n"


def valid_study() -> dict:
    return {
        "name": "hostile",
        "machine": "default",
        "strokes_per_minute": 65,
        "skip_revolutions": 0,
        "revolutions": 1,
        "steps_per_revolution": 60,
        "metrics": ["friction_work", "torque_peak"],
        "design": {"kind": "grid"},
        "parameters": {"mass.reciprocating": {"start": 100.0, "stop": 500.0, "num": 3}},
    }


ANY = st.one_of(
    st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=12),
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.lists(st.integers(-5, 5), max_size=3),
)
NAME = st.text(
    st.characters(codec="utf-8", exclude_categories=("Cs",)), min_size=1, max_size=20
).filter(lambda s: s.strip() == s and s)


@st.composite
def malformed_study(draw):
    """(study dict, a word the one-line error must contain)."""
    doc = valid_study()
    kind = draw(
        st.sampled_from(
            [
                "unknown_key",
                "unknown_parameter",
                "wrong_type",
                "bad_num",
                "bad_value",
                "design_kind",
                "bad_name",
                "both_fixed",
                "metric",
                "range",
                "fixed_value",
            ]
        )
    )
    p = doc["parameters"]
    if kind == "unknown_key":
        key = draw(NAME.filter(lambda s: s not in valid_study()))
        doc[key] = draw(ANY)
        return doc, key
    if kind == "unknown_parameter":
        key = draw(NAME.filter(lambda s: "." not in s or not s.startswith(("support", "mass"))))
        p[key] = {"values": [1.0]}
        return doc, key
    if kind == "wrong_type":
        key = draw(
            st.sampled_from(["revolutions", "skip_revolutions", "steps_per_revolution", "metrics"])
        )
        doc[key] = draw(st.one_of(st.text(max_size=5), st.floats(0.5, 9.5), st.booleans()))
        return doc, key
    if kind == "bad_num":
        p["mass.reciprocating"]["num"] = draw(
            st.one_of(
                st.floats(allow_nan=True).filter(
                    lambda x: x != int(x) if math.isfinite(x) else True
                ),
                st.integers(-100, 0),
                st.text(max_size=3),
            )
        )
        return doc, "num"
    if kind == "bad_value":
        v = draw(
            st.one_of(
                st.text(max_size=8),
                st.booleans(),
                st.floats(max_value=-1e-300),
                st.floats(min_value=1.0001e9),
                st.just(math.nan),
                st.just(math.inf),
            )
        )
        p["mass.reciprocating"] = {"values": [200.0, v]}
        return doc, "mass.reciprocating"
    if kind == "design_kind":
        doc["design"]["kind"] = draw(NAME.filter(lambda s: s not in ("grid", "random", "lhs")))
        return doc, "design.kind"
    if kind == "bad_name":
        doc["name"] = draw(
            st.one_of(
                st.just("../../escape"),
                st.just("/tmp/abs"),
                st.builds(lambda a: f"a/{a}", NAME),
                st.builds(lambda a: f".{a}", NAME),
                st.just(""),
            )
        )
        return doc, "name"
    if kind == "both_fixed":
        doc["fixed"] = {"mass.reciprocating": 300.0}
        return doc, "mass.reciprocating"
    if kind == "metric":
        doc["metrics"] = ["torque_peak", draw(NAME)]
        return doc, "metrics"
    if kind == "range":
        doc["revolutions"] = draw(st.integers(-(10**6), 0))
        return doc, "revolutions"
    doc["fixed"] = {"support_A.kind": draw(st.one_of(st.integers(4, 10**6), st.floats(), NAME))}
    return doc, "support_A.kind"


def no_results(out: pathlib.Path):
    assert not out.exists() or not any(out.iterdir()), list(out.iterdir())


@HYPOTHESIS
@given(case=malformed_study())
def test_generated_malformed_studies_are_one_line_errors(tmp_path, fmu_path, case):
    doc, word = case
    f = tmp_path / "gen.toml"
    f.write_text(to_toml(doc), encoding="utf-8")
    out = tmp_path / "out"
    p = run([f, "--fmu", fmu_path, "--out-dir", out, "--no-progress"])
    line = assert_user_error(p, str(f))
    # The key (or the parameter) is named; its value follows as "key = value" or after it.
    assert word in line or json.dumps(word)[1:-1] in line or repr(word)[1:-1] in line, line
    no_results(out)


@HYPOTHESIS
@given(data=st.binary(max_size=200))
def test_generated_garbage_files_are_one_line_errors(tmp_path, fmu_path, data):
    f = tmp_path / "garbage.toml"
    f.write_bytes(data)
    out = tmp_path / "out"
    p = run([f, "--fmu", fmu_path, "--out-dir", out, "--no-progress"])
    assert_user_error(p, str(f))
    no_results(out)


OPTIONS = st.one_of(
    st.tuples(st.just("--workers"), st.sampled_from(["0", "-1", "abc", "1.5", "", "nan"])),
    st.tuples(st.just("--batch-size"), st.sampled_from(["0", "-3", "x", "1e3"])),
    st.tuples(st.just("--max-cases"), st.sampled_from(["0", "-1", "many", "2.5"])),
    st.tuples(st.just("--stop-after"), st.sampled_from(["0", "-1", "soon"])),
    st.tuples(st.just("--connect-timeout"), st.sampled_from(["0", "-1", "nan", "inf", "x"])),
    st.tuples(
        st.just("--scheduler"),
        st.text(st.characters(codec="ascii", exclude_characters=":\x00"), min_size=1, max_size=20),
    ),
    st.tuples(st.sampled_from(["--bogus", "--max-case", "--frsh"]), st.just("1")),
    st.tuples(st.sampled_from(["--fmu", "--out-dir", "--workers", "--scheduler"]), st.just("--")),
)


@HYPOTHESIS
@given(opt=OPTIONS)
def test_generated_bad_options_are_one_line_errors(tmp_path, fmu_path, opt):
    f = tmp_path / "ok.toml"
    f.write_text(to_toml(valid_study()))
    out = tmp_path / "out"
    name, value = opt
    p = run([f, "--fmu", fmu_path, "--out-dir", out, "--no-progress", f"{name}={value}"])
    assert_user_error(p, name)
    no_results(out)


# ---- named findings ------------------------------------------------------------------------

NAMED_STUDIES = {
    "unknown parameter": (
        '[parameters]\n"mass.reciprocatin" = { values = [1.0] }\n',
        "unknown parameter 'mass.reciprocatin'",
    ),
    "values heavy": (
        '[parameters]\n"mass.reciprocating" = { values = ["heavy"] }\n',
        "values[0] = 'heavy'; allowed: a number",
    ),
    "spec a string": ('[parameters]\n"mass.reciprocating" = "300"\n', "= '300'; allowed: a table"),
    "unknown design kind": (
        '[design]\nkind = "sobol"\n[parameters]\n"mass.reciprocating" = { values = [1.0] }\n',
        "design.kind = 'sobol'; allowed: grid, random, lhs",
    ),
    "unknown key": (
        'strokes_per_minut = 60\n[parameters]\n"mass.reciprocating" = { values = [1.0] }\n',
        "unknown key 'strokes_per_minut'",
    ),
    "num 2.5": (
        '[parameters]\n"mass.reciprocating" = { start = 1, stop = 2, num = 2.5 }\n',
        "num = 2.5; allowed: an integer",
    ),
    "fixed and parameters": (
        '[fixed]\n"mass.reciprocating" = 3.0\n[parameters]\n"mass.reciprocating" = { values = [1.0] }\n',
        "in both [fixed] and [parameters]",
    ),
    "name escapes": (
        'name = "../../escape"\n[parameters]\n"mass.reciprocating" = { values = [1.0] }\n',
        "name = '../../escape'",
    ),
    "duplicate key": (
        'revolutions = 1\nrevolutions = 2\n[parameters]\n"mass.reciprocating" = { values = [1.0] }\n',
        "not valid TOML",
    ),
    "ten to the fifteen": (
        '[parameters]\n"mass.reciprocating" = { start = 1, stop = 2, num = 100000000 }\n'
        '"link.E" = { start = 1e11, stop = 2e11, num = 10000000 }\n',
        "1,000,000,000,000,000 cases; allowed: at most 1,000,000",
    ),
    "50 000-deep arrays": (
        "revolutions = " + "[" * 50_000 + "]" * 50_000 + "\n",
        "nested too deep",
    ),
}


@pytest.mark.parametrize("name", list(NAMED_STUDIES))
def test_named_study_errors(tmp_path, fmu_path, name):
    text, words = NAMED_STUDIES[name]
    f = tmp_path / "named.toml"
    f.write_text(text)
    out = tmp_path / "out"
    t0 = time.monotonic()
    p = run([f, "--fmu", fmu_path, "--out-dir", out, "--no-progress"])
    assert_user_error(p, str(f), words)
    assert time.monotonic() - t0 < 30  # refused before a cluster starts
    no_results(out)


def test_fmu_that_is_not_the_pump_or_not_an_fmu(tmp_path, fmu_path):
    f = tmp_path / "s.toml"
    f.write_text(to_toml(valid_study()))
    drive = pathlib.Path(fmu_path).parent / "DriveTrain.fmu"
    p = run([f, "--fmu", drive, "--out-dir", tmp_path / "o"])
    assert_user_error(p, "not a ReciprocatingDrive FMU")
    junk = tmp_path / "junk.fmu"
    junk.write_text("not a zip")
    p = run([f, "--fmu", junk, "--out-dir", tmp_path / "o"])
    assert_user_error(p, f"--fmu {junk}", "not a readable FMU")
    no_results(tmp_path / "o")


def rows_of(csv_path: pathlib.Path) -> list[str]:
    return csv_path.read_text().splitlines()[1:]


def test_stale_results_are_refused_and_fresh_starts_afresh(tmp_path, fmu_path):
    """Issue finding 1: a study edited under the same name (mass 100..500 -> 100..900) must not
    reuse the old rows; the FMU changed (another version in its model description) neither."""
    doc = valid_study()
    doc["parameters"] = {"mass.reciprocating": {"start": 100.0, "stop": 500.0, "num": 5}}
    f, out = tmp_path / "s.toml", tmp_path / "out"
    f.write_text(to_toml(doc))
    common = ["--fmu", fmu_path, "--out-dir", out, "--no-progress", "--workers", "1"]
    p = run([f, *common])
    assert p.returncode == 0, p.stderr
    csv_path = out / "hostile.csv"
    before = csv_path.read_bytes()
    doc["parameters"]["mass.reciprocating"]["stop"] = 900.0
    f.write_text(to_toml(doc))
    p = run([f, *common])
    assert_user_error(p, str(csv_path), "the study's content", "--fresh")
    assert csv_path.read_bytes() == before  # untouched
    # Another FMU build (its version differs): refused too, naming the FMU.
    other = tmp_path / "other.fmu"
    with zipfile.ZipFile(fmu_path) as zi, zipfile.ZipFile(other, "w") as zo:
        for item in zi.infolist():
            data = zi.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'version="0.1.0"', b'version="9.9.9"', 1)
            zo.writestr(item, data)
    doc["parameters"]["mass.reciprocating"]["stop"] = 500.0
    f.write_text(to_toml(doc))
    p = run([f, "--fmu", other, *common[2:]])
    assert_user_error(p, "the FMU (its GUID or version) changed")
    # --fresh: the edited study computed from scratch, equal to a clean run in another folder.
    doc["parameters"]["mass.reciprocating"]["stop"] = 900.0
    f.write_text(to_toml(doc))
    p = run([f, *common, "--fresh"])
    assert p.returncode == 0, p.stderr
    assert "5 cases computed, 0 found" in p.stdout
    clean = tmp_path / "clean"
    p = run([f, "--fmu", fmu_path, "--out-dir", clean, "--no-progress", "--workers", "1"])
    assert p.returncode == 0, p.stderr

    def metrics(path):
        return [",".join(r.split(",")[:4]) for r in rows_of(path)]  # case, mass, two metrics

    assert metrics(csv_path) == metrics(clean / "hostile.csv")
    assert metrics(csv_path)[-1].split(",")[1] == "900.0"


def test_every_case_rejected_exits_1(tmp_path, fmu_path):
    """Issue finding 13: a sweep whose every case is rejected must not exit 0."""
    doc = valid_study()
    # rod 0.15 m < crank radius 0.2 m: the crank-slider cannot assemble, in every case.
    doc["fixed"] = {"geometry.rod_length": 0.15}
    f = tmp_path / "s.toml"
    f.write_text(to_toml(doc))
    p = run([f, "--fmu", fmu_path, "--out-dir", tmp_path / "o", "--no-progress", "--workers", "1"])
    assert_user_error(p, "every case (3) was rejected", "cannot assemble", code=1)


def _serve(kind: str):
    """A TCP server on 127.0.0.1 that is not a Dask scheduler: "http" answers like an HTTP server
    (after a request), "silent" accepts and never sends. Returns (port, stop)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    srv.settimeout(0.2)
    stop = threading.Event()
    conns = []

    def loop():
        while not stop.is_set():
            try:
                c, _ = srv.accept()
            except TimeoutError:
                continue
            conns.append(c)
            if kind == "http":
                c.settimeout(0.5)
                try:
                    if c.recv(1024):
                        c.sendall(b"HTTP/1.0 400 Bad Request\r\n\r\n")
                except OSError:
                    pass

    th = threading.Thread(target=loop, daemon=True)
    th.start()

    def close():
        stop.set()
        th.join(5)
        for c in conns:
            c.close()
        srv.close()

    return srv.getsockname()[1], close


@pytest.mark.parametrize("kind", ["http", "silent"])
def test_scheduler_that_is_not_dask_is_a_bounded_error(tmp_path, fmu_path, kind):
    """Issue finding 7: --scheduler pointed at an HTTP server hung beyond 75 s."""
    port, close = _serve(kind)
    try:
        f = tmp_path / "s.toml"
        f.write_text(to_toml(valid_study()))
        t0 = time.monotonic()
        p = run(
            [
                f,
                "--fmu",
                fmu_path,
                "--out-dir",
                tmp_path / "o",
                "--scheduler",
                f"tcp://127.0.0.1:{port}",
                "--connect-timeout",
                "2",
            ],
            timeout=60,
        )
        assert time.monotonic() - t0 < 30
        assert_user_error(p, f"--scheduler tcp://127.0.0.1:{port}", "not a Dask scheduler")
        no_results(tmp_path / "o")
    finally:
        close()


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize(
    "addr,words",
    [
        ("notaurl", "missing port"),
        ("http://127.0.0.1:80", "scheme 'http'"),
        ("tcp://127.0.0.1:99999", "port 99999"),
        ("REFUSED", "connection refused"),
        ("tcp://nosuch.invalid:8786", "cannot be resolved"),
    ],
)
def test_scheduler_address_errors_are_one_line(tmp_path, fmu_path, addr, words):
    """Issue finding 10: refused, unresolvable, malformed addresses."""
    if addr == "REFUSED":
        addr = f"tcp://127.0.0.1:{_closed_port()}"
    f = tmp_path / "s.toml"
    f.write_text(to_toml(valid_study()))
    p = run(
        [
            f,
            "--fmu",
            fmu_path,
            "--out-dir",
            tmp_path / "o",
            "--scheduler",
            addr,
            "--connect-timeout",
            "5",
        ],
        timeout=60,
    )
    assert_user_error(p, "--scheduler", words)
    no_results(tmp_path / "o")


BIG = """name = "big"
skip_revolutions = 0
revolutions = 1
steps_per_revolution = 90
[parameters]
"mass.reciprocating" = { start = 100, stop = 500, num = 1000 }
"link.E" = { start = 1e11, stop = 2e11, num = 1000 }
"""


def test_ctrl_c_keeps_all_but_seconds_and_says_how_to_resume(tmp_path, fmu_path):
    """Issue findings 6 and 13: a sweep of 10⁶ cases stopped by SIGINT (Ctrl-C). It writes each
    batch of about a second as it finishes, so the file grows many times before the signal; the
    signal ends it with one line "stopped ...; resume with: ..." and exit 130, no traceback; and
    the command it names resumes the sweep without recomputing a kept case."""
    f, out = tmp_path / "big.toml", tmp_path / "out"
    f.write_text(BIG)
    cmd = [sys.executable, str(SWEEP), str(f), "--fmu", fmu_path, "--out-dir", str(out),
           "--workers", "2", "--no-progress"]  # fmt: skip
    p = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_default_sigint
    )
    csv_path = out / "big.csv"
    sizes, deadline = [], time.monotonic() + 90
    try:
        while time.monotonic() < deadline and len(set(sizes)) < 6:
            if csv_path.is_file():
                sizes.append(csv_path.read_bytes().count(b"\n"))
            time.sleep(0.1)
        seen = csv_path.read_bytes().count(b"\n") - 1
        t_signal = time.monotonic()
        p.send_signal(signal.SIGINT)
        stdout, stderr = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(10)
    stop_seconds = time.monotonic() - t_signal
    assert "Traceback" not in stdout + stderr
    assert p.returncode == 130, stderr
    (line,) = stderr.strip().splitlines()
    assert "stopped (" in line and "resume with: " in line, line
    kept = rows_of(csv_path)
    print(f"rows seen before SIGINT {seen}, kept {len(kept)}, growth steps {len(set(sizes))}, "
          f"stopped in {stop_seconds:.1f} s")  # fmt: skip
    assert len(set(sizes)) >= 6  # written in small steps, not four batches per worker
    assert len(kept) >= seen and stop_seconds < 30
    # The printed command resumes: only new cases (here 20 of them) are computed.
    resume = line.split("resume with: ", 1)[1]
    import shlex

    r = subprocess.run(
        [*shlex.split(resume), "--stop-after", "20"], capture_output=True, text=True, timeout=120
    )
    assert r.returncode == 0, r.stderr
    assert f"20 cases computed, {len(kept)} found" in r.stdout


def _peak_rss_kb(args, tmp_path) -> tuple[int, subprocess.CompletedProcess]:
    """Runs the command under a fresh Python that reports the largest resident set of the
    command and its descendants (getrusage of its children: the sweep and its workers) [kB]."""
    report = tmp_path / "rss.txt"
    wrapper = (
        "import resource, subprocess, sys; r = subprocess.run(sys.argv[2:]); "
        "open(sys.argv[1], 'w').write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)); "
        "sys.exit(r.returncode)"
    )
    p = subprocess.run(
        [sys.executable, "-c", wrapper, str(report), sys.executable, str(SWEEP), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        preexec_fn=_default_sigint,
    )
    return int(report.read_text()), p


def test_size_of_a_study_costs_no_memory(tmp_path, fmu_path):
    """Issue finding 8: 10⁶ cases took 1.1 GB before the first case, 10¹⁵ ended in MemoryError.
    Planning is lazy: in this process, planning 10¹⁵ cases and asking for the last one allocates
    under 1 MB (tracemalloc); through the command, a study of 10¹⁵ cases (allowed by --max-cases)
    that computes 4 cases and stops has the same peak memory as a study of 4 cases (to 50 MB)."""
    import tracemalloc

    from reciprocating_drive.sweeps.study import study_from_dict

    doc = {
        "parameters": {
            "mass.reciprocating": {"start": 1, "stop": 2, "num": 10**8},
            "link.E": {"start": 1e11, "stop": 2e11, "num": 10**7},
        }
    }

    def planning_peak(d):
        tracemalloc.start()
        s = study_from_dict(d, max_cases=10**15)
        last = s.case(s.n_cases - 1)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return s, last, peak

    small_doc = {"parameters": {"mass.reciprocating": {"values": [1.0, 2.0]}}}
    planning_peak(small_doc)  # imports and the model description, read once
    _, _, peak_small = planning_peak(small_doc)
    s, last, peak = planning_peak(doc)
    assert s.n_cases == 10**15 and last == {"mass.reciprocating": 2.0, "link.E": 2e11}
    print(f"planning peak: 2 cases {peak_small} B, 10^15 cases {peak} B")
    assert peak - peak_small < 1 << 20, (peak, peak_small)

    big = tmp_path / "big.toml"
    big.write_text(
        BIG.replace("num = 1000 }", "num = 100000000 }", 1).replace(
            "num = 1000 }", "num = 10000000 }"
        )
    )
    small = tmp_path / "small.toml"
    small.write_text(BIG.replace("num = 1000 }", "num = 2 }"))
    common = ["--fmu", fmu_path, "--no-progress", "--workers", "1", "--batch-size", "1"]
    # The limit first: refused without --max-cases.
    p = run([big, *common, "--out-dir", tmp_path / "refused"])
    assert_user_error(p, "1,000,000,000,000,000 cases", "--max-cases")
    rss_small, p = _peak_rss_kb([small, *common, "--out-dir", tmp_path / "s"], tmp_path)
    assert p.returncode == 0, p.stderr
    rss_big, p = _peak_rss_kb(
        [big, *common, "--out-dir", tmp_path / "b", "--max-cases", 10**15, "--stop-after", 4],
        tmp_path,
    )
    assert p.returncode == 0, p.stderr
    assert "4 cases computed" in p.stdout
    print(f"peak RSS: small study {rss_small} kB, 10^15 cases {rss_big} kB")
    assert rss_big - rss_small < 50_000


def test_message_lines_have_no_newline_from_values(tmp_path, fmu_path):
    """A value with a newline in it (a TOML string) still gives one line."""
    f = tmp_path / "nl.toml"
    f.write_text('machine = "a\\nb"\n[parameters]\n"mass.reciprocating" = { values = [1.0] }\n')
    p = run([f, "--fmu", fmu_path, "--out-dir", tmp_path / "o"])
    assert_user_error(p, "machine = 'a\\nb'")
    assert io.StringIO(p.stderr).read().count("\n") == 1


@pytest.mark.parametrize(
    "damage,words",
    [
        ("1,200.0,1,2\n", "line 3: 4 fields, the header has 10"),
        ("x" * 10 + "\n", "line 3: 1 fields"),
        ("1,2,3,4,5,6,7,8,9,10,11,12\n", "line 3: 12 fields"),
        ("1,200.0,1,2,maybe,,0,0,pid 1,{fp}\n", "line 3: status = 'maybe'"),
        ("one,200.0,1,2,ok,,0,0,pid 1,{fp}\n", "line 3: case = 'one'"),
    ],
)
def test_damaged_result_file_is_refused(tmp_path, fmu_path, damage, words):
    """A result file with a damaged line in it (not the last line a kill may cut) is refused with
    the line named, before any cluster starts; the file is left as it was."""
    from reciprocating_drive.sweeps.study import load_study
    from reciprocating_drive.sweeps.sweep import columns, fingerprint

    f, out = tmp_path / "s.toml", tmp_path / "out"
    f.write_text(to_toml(valid_study()))
    study = load_study(f, fmu=fmu_path)
    fp = fingerprint(study, fmu_path)
    out.mkdir()
    csv_path = out / "hostile.csv"
    text = (
        ",".join(columns(study)) + "\n" + f"0,100.0,1.0,2.0,ok,,0.1,0.1,pid 1,{fp}\n"
        + damage.format(fp=fp) + f"2,500.0,1.0,2.0,ok,,0.1,0.1,pid 1,{fp}\n"
    )  # fmt: skip
    csv_path.write_text(text)
    p = run([f, "--fmu", fmu_path, "--out-dir", out, "--no-progress"], timeout=60)
    assert_user_error(p, str(csv_path), words, "--fresh")
    assert csv_path.read_text() == text
