"""File names built from hostile datablock names stay inside the output folder and never share a file."""
import os
import random

from addon.core.io.names import MAX_STEM, file_stems

HOSTILE = ["../../evil", "..", ".", "", "/", "/etc/passwd", "a/b", "a\\b", "C:evil", "~", ".hidden", "-rf",
           "CON", "nul.txt", "Floor", "floor", "FLOOR", "a b", "a_b", "a?b", "Сфера", "球", "x" * 300,
           "tab\tname", "new\nline", "Floor.001", "Floor_001"]


def test_stems_are_single_components_inside_the_folder(tmp_path):
    out = os.path.join(str(tmp_path), "out")
    stems = file_stems(HOSTILE)
    assert set(stems) == set(HOSTILE)
    for name, stem in stems.items():
        path = os.path.normpath(os.path.join(out, f"{stem}_ao.exr"))
        assert os.path.dirname(path) == out, (name, stem)
        assert stem and not stem.startswith((".", "-")) and len(stem) <= MAX_STEM + 9
        assert all(c.isascii() and (c.isalnum() or c in "._-") for c in stem), (name, stem)
        assert stem.split(".")[0].upper() not in ("CON", "NUL")


def test_stems_are_unique_ignoring_case_and_do_not_depend_on_order():
    stems = file_stems(HOSTILE)
    assert len({s.casefold() for s in stems.values()}) == len(HOSTILE)
    shuffled = HOSTILE[:]
    random.Random(3).shuffle(shuffled)
    assert file_stems(shuffled) == stems


def test_plain_names_are_kept_and_twins_are_told_apart():
    stems = file_stems(["Floor", "Box.001", "Sphere", "Back Wall", "a b", "a_b", "Wall", "wall", "../../evil"])
    assert stems["Floor"] == "Floor" and stems["Box.001"] == "Box.001" and stems["Sphere"] == "Sphere"
    assert stems["Back Wall"] == "Back_Wall" and stems["../../evil"] == "evil"
    assert stems["a b"] != stems["a_b"] and stems["a b"].startswith("a_b-") and stems["a_b"].startswith("a_b-")
    assert stems["Wall"].casefold() != stems["wall"].casefold()
    assert file_stems(["evil", "../../evil"])["evil"].startswith("evil-")
