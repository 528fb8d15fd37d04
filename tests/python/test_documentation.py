"""The project documents itself (docs/): every variable is documented, every `docs/<page>.md §N`
citation in the repository names a section that exists, every link and figure resolves, nothing
points outside the repository, the figures can be regenerated, and the defaults stated in
docs/model.md §8 are the FMU's start values (read from the built FMU, not from the docs' source)."""

from __future__ import annotations

import importlib.util
import pathlib
import re
import subprocess

import pytest
from conftest import ROOT

DOCS = ROOT / "docs"


def tracked_text_files():
    out = subprocess.run(
        ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout
    for rel in out.split():
        p = ROOT / rel
        if p.suffix in (".png", ".fmu", ".csv", ".lock", ".ssp") or not p.is_file():
            continue
        try:
            yield rel, p.read_text()
        except UnicodeDecodeError:
            continue


def headings(page: pathlib.Path) -> list[str]:
    return [
        line.lstrip("#").strip() for line in page.read_text().splitlines() if line.startswith("#")
    ]


def section_numbers(page: pathlib.Path) -> set[str]:
    out = set()
    for h in headings(page):
        m = re.match(r"(\d+(?:\.\d+)*)\.?\s", h)
        if m:
            out.add(m.group(1))
    return out


def test_every_variable_is_in_the_interface_page(model_description):
    text = (DOCS / "fmi-interface.md").read_text().split("<!-- variables:begin -->")[1]
    rows = {m.group(1): m.group(0) for m in re.finditer(r"^\| `([^`]+)` \|.*$", text, re.M)}
    for v in model_description.modelVariables:
        assert v.name in rows, f"{v.name} missing from docs/fmi-interface.md"
        assert f"| {v.causality} |" in rows[v.name] and f"| {v.valueReference} |" in rows[v.name], (
            rows[v.name]
        )
    assert len(rows) == len(model_description.modelVariables)


def test_every_section_citation_exists():
    pages = {p.name: section_numbers(p) for p in DOCS.glob("*.md")}
    cite = re.compile(r"docs/([a-z-]+\.md)`?\s*§\s*(\d+(?:\.\d+)*)")
    # A bare "§N" in a file that names docs/model.md refers to that page.
    bare = re.compile(r"§\s*(\d+(?:\.\d+)*)")
    missing = []
    for rel, text in tracked_text_files():
        for m in cite.finditer(text):
            page, sec = m.group(1), m.group(2)
            if page not in pages or sec not in pages[page]:
                missing.append(f"{rel}: docs/{page} §{sec}")
        if "docs/model.md" in text and not rel.startswith("docs/"):
            for m in bare.finditer(text):
                if m.group(1).rstrip(".") not in pages["model.md"]:
                    missing.append(f"{rel}: §{m.group(1)}")
    assert not missing, "citations of sections that do not exist:\n" + "\n".join(
        sorted(set(missing))
    )


def test_links_and_figures_resolve():
    link = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
    for page in list(DOCS.glob("*.md")) + [ROOT / "README.md"]:
        for m in link.finditer(page.read_text()):
            target = m.group(1)
            if "://" in target:
                continue
            assert (page.parent / target).exists(), (
                f"{page.relative_to(ROOT)}: {target} does not exist"
            )


def test_anchors_resolve():
    """Links like model.md#8-default-machine-and-presets point at a heading of that page
    (GitHub's anchor rule: lower case, punctuation dropped, spaces to hyphens)."""

    def anchor(h):
        return re.sub(r"\s", "-", re.sub(r"[^\w\s-]", "", h.lower()))

    for page in DOCS.glob("*.md"):
        for m in re.finditer(r"\]\(([a-z-]+\.md)#([^)]+)\)", page.read_text()):
            target = DOCS / m.group(1)
            assert m.group(2) in {anchor(h) for h in headings(target)}, f"{page.name}: {m.group(0)}"


def test_nothing_points_outside_the_repository():
    bad = re.compile(r"\.\./shared|/work" r"/shared|(?<![\w/-])physics\.md|(?<![\w/-])fmi\.md")
    hits = [
        f"{rel}: {m.group(0)}" for rel, text in tracked_text_files() for m in bad.finditer(text)
    ]
    assert not hits, "\n".join(hits)


def test_defaults_in_the_model_page_are_the_fmus_start_values(model_description):
    start = {v.name: v.start for v in model_description.modelVariables if v.start is not None}
    text = (DOCS / "model.md").read_text()
    sec = text.split("## 8.")[1].split("## 9.")[0]
    checked = 0
    for line in sec.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 2:
            continue
        names = [n.strip() for n in cells[0].split(",")]
        values = [v.strip() for v in cells[1].split(", ")]
        if not all(n in start for n in names) or len(values) != len(names):
            continue
        for n, v in zip(names, values):
            token = v.split()[0]
            want = start[n]
            if token in ("true", "false"):
                assert str(want).lower() == token, (n, want, v)
            else:
                assert float(want) == pytest.approx(float(token), rel=1e-12, abs=1e-15), (
                    n,
                    want,
                    v,
                )
            checked += 1
    assert checked >= 10


#: Figures a test takes rather than scripts/make_docs.py (a browser's screenshot), and that test.
TAKEN_BY_TESTS = {"twin_page.png": "tests/python/test_page_operator.py"}


def test_figures_regenerate(tmp_path, fmu_path, monkeypatch):
    """scripts/make_docs.py writes every figure the pages show."""
    monkeypatch.setenv("RD_FMU", fmu_path)
    spec = importlib.util.spec_from_file_location("make_docs", ROOT / "scripts" / "make_docs.py")
    make_docs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_docs)
    make_docs.FMU = pathlib.Path(fmu_path)
    make_docs.main(["--out", str(tmp_path)])
    shown = set()
    for page in DOCS.glob("*.md"):
        shown |= set(re.findall(r"figures/([\w.-]+\.png)", page.read_text()))
    assert shown, "the pages show no figure"
    for name in shown - set(TAKEN_BY_TESTS):
        png = tmp_path / name
        assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    for name, test in TAKEN_BY_TESTS.items():
        assert f'figures" / "{name}"' in (ROOT / test).read_text(), (name, test)
    # The variable table in the page is what the script generates from the FMU.
    table = make_docs.variable_table(pathlib.Path(fmu_path))
    assert table in (DOCS / "fmi-interface.md").read_text(), (
        "docs/fmi-interface.md: run scripts/make_docs.py --table-only"
    )


def test_fmu_carries_the_documentation_as_html(fmu_path):
    """documentation/ of the built FMU: index.html (variables) links every page of docs/ as HTML,
    and every relative link and image of every page resolves inside the FMU."""
    import zipfile
    from html.parser import HTMLParser

    with zipfile.ZipFile(fmu_path) as z:
        names = set(z.namelist())
        pages = {p.stem for p in DOCS.glob("*.md")}
        for stem in pages:
            assert f"documentation/{stem}.html" in names, stem
        index = z.read("documentation/index.html").decode()
        for stem in pages:
            assert f'href="{stem}.html"' in index, stem

        class Refs(HTMLParser):
            def __init__(self):
                super().__init__()
                self.refs, self.ids = [], set()

            def handle_starttag(self, tag, attrs):
                a = dict(attrs)
                if "id" in a:
                    self.ids.add(a["id"])
                for key in ("href", "src"):
                    if a.get(key):
                        self.refs.append(a[key])

        parsed = {}
        for n in names:
            if n.startswith("documentation/") and n.endswith(".html"):
                p = Refs()
                p.feed(z.read(n).decode())
                parsed[n] = p
        for n, p in parsed.items():
            for ref in p.refs:
                if "://" in ref or ref.startswith("mailto:"):
                    continue
                path, _, frag = ref.partition("#")
                target = f"documentation/{path}" if path else n
                assert target in names, f"{n}: {ref}"
                if frag and target in parsed:
                    assert frag in parsed[target].ids, f"{n}: {ref}"
        # The model page shows the mechanism sketches.
        assert 'src="figures/crank_slider.png"' in z.read("documentation/model.html").decode()


def _section(page: str, heading: str) -> str:
    text = (DOCS / page).read_text()
    return text.split(f"\n{heading}\n", 1)[1].split("\n## ", 1)[0]


def test_every_unit_of_both_fmus_is_listed(fmu_path):
    """docs/fmi-interface.md "Units" names every unit either FMU declares (N.m.s/rad was missing)."""
    from fmpy import read_model_description

    units = _section("fmi-interface.md", "## Units").split("\n\n")[0]
    listed = {u.strip(" .,`\n") for u in re.split(r"[:,]|\band\b", units)}
    listed |= set(re.findall(r"\b[\w./]+\b", units))
    for name in ("ReciprocatingDrive.fmu", "DriveTrain.fmu"):
        md = read_model_description(str(pathlib.Path(fmu_path).parent / name))
        for u in md.unitDefinitions:
            assert u.name in listed, f"{name}: unit {u.name} is not in docs/fmi-interface.md Units"


def test_variable_table_has_descriptions_and_rod_angle_with_the_rod(model_description):
    """The generated table gives each variable the model description's description, and lists
    rod.angle with the connecting rod's outputs (an elastic rod's cage oscillation), not under
    kinematics."""
    text = (DOCS / "fmi-interface.md").read_text().split("<!-- variables:begin -->")[1]
    text = text.split("<!-- variables:end -->")[0]
    section, where = None, {}
    for line in text.splitlines():
        if line.startswith("**"):
            section = line.strip("*")
        m = re.match(r"^\| `([^`]+)` \|(.*)\|$", line)
        if m:
            where[m.group(1)] = (section, m.group(2))
    for v in model_description.modelVariables:
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", where[v.name][1])]
        assert cells[-1].replace("\\|", "|") == v.description, v.name
    assert where["rod.angle"][0].startswith("Outputs: connecting rod")
    assert where["rod.angular_velocity"][0] == where["rod.angle"][0]
    assert "kinematics" not in where["rod.angle"][0]
    assert where["suspension.position"][0] == "Outputs: kinematics"


def test_which_parameters_act_names_real_parameters_and_tilt_of_a_gland_has_no_effect(
    model_description, fmu_path
):
    """The "Which parameters act" table names only parameters of the FMU, and its claim about the
    tilt holds in the FMU: on the default machine (C a frame-fixed pin, the gland; B a two-edge
    guide) varying support_C.tilt changes no output bit, varying support_B.tilt changes the
    friction."""
    from reciprocating_drive import Fmu

    table = _section("fmi-interface.md", "## Variables").split("### Which parameters act")[1]
    table = table.split("<!-- variables:begin -->")[0]
    names = {v.name for v in model_description.modelVariables}
    cited = set(re.findall(r"`([a-z_A-Z]+\.[a-z_A-Z.]+)`", table))
    # support_X.* stands for each of A, B and C; rod.* for the group.
    expanded = {c.replace("_X.", f"_{x}.") for c in cited for x in "ABC"}
    unknown = {c for c in expanded if not c.endswith(".*")} - names
    assert len(cited) > 20 and not unknown, unknown

    outs = ["rod.force", "link.friction_total", "support_C.reaction", "guide.reaction"]

    def run(values):
        with Fmu(fmu_path) as f:
            f.start(values)
            rows = []
            for _ in range(40):
                f.step(0.02)
                rows.append(f.get(outs))
        return rows

    base = run({})
    assert run({"support_C.tilt": 0.01}) == base
    assert run({"support_C.tilt": -0.02}) == base
    assert run({"support_B.tilt": 0.001}) != base
