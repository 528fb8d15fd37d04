"""The sketches of docs/model.md (scripts/make_docs.py): drawn for a screen (at least 1 600 pixels
wide), no two labels overlap (their boxes on the rendered canvas), and the link sketch labels the
sections l1..l4 that its title promises."""

from __future__ import annotations

import importlib.util

import pytest
from conftest import ROOT
from matplotlib.text import Text

spec = importlib.util.spec_from_file_location("make_docs", ROOT / "scripts" / "make_docs.py")
make_docs = importlib.util.module_from_spec(spec)
spec.loader.exec_module(make_docs)


@pytest.mark.parametrize("name", make_docs.SKETCHES)
def test_sketch_is_sharp_and_its_labels_do_not_overlap(name, tmp_path):
    from PIL import Image

    fig = getattr(make_docs, f"draw_{name}")()
    assert not make_docs.text_overlaps(fig), make_docs.text_overlaps(fig)
    path = tmp_path / f"{name}.png"
    make_docs._save(fig, path)
    width, _ = Image.open(path).size
    assert width >= 1600, width
    # The committed figure is the one the script draws (regenerate: scripts/make_docs.py).
    committed = Image.open(ROOT / "docs" / "figures" / f"{name}.png")
    assert committed.size == Image.open(path).size


def test_overlap_check_sees_an_overlap():
    """The check itself: two labels at one place are reported."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.annotate("centre bearing", (0.5, 0.5))
    ax.annotate("equalizer", (0.52, 0.5))
    assert make_docs.text_overlaps(fig) == [("centre bearing", "equalizer")]
    plt.close(fig)


def test_supports_sketch_labels_sections_l1_to_l4():
    fig = make_docs.draw_supports()
    texts = {t.get_text() for t in fig.findobj(Text)}
    assert {"l1", "l2", "l3", "l4"} <= texts
    assert any("supports A, B, C" in t for t in texts)
    assert any(t.startswith("A:") for t in texts) and any(t.startswith("C:") for t in texts)
