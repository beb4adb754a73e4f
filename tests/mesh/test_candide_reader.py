import numpy as np
import pytest

from aamtrack.errors import InputError
from aamtrack.mesh.candide import read_wfm
from conftest import shared_path

TINY = """# a comment
# VERTEX LIST:
3
0 0 0
1 0 0
0 1 0.5

# FACE LIST:
1
0 1 2

# ANIMATION UNITS LIST:
1

# AUV0   Tiny unit
1
2 0.0 0.1 0.0

# SHAPE UNITS LIST:
1

# Width
2
1 0.2 0 0
0 -0.2 0 0
"""


def test_reads_tiny_file(tmp_path):
    p = tmp_path / "tiny.wfm"
    p.write_text(TINY)
    c = read_wfm(p)
    assert c.vertices.shape == (3, 3) and c.vertices[2, 2] == 0.5
    assert c.triangles.tolist() == [[0, 1, 2]]
    assert c.anim_names == ("AUV0   Tiny unit",) and c.anim_units[0, 2, 1] == pytest.approx(0.1)
    assert c.shape_names == ("Width",) and c.shape_units[0, 0, 0] == pytest.approx(-0.2)
    assert c.anim_index("AUV0") == 0


@pytest.mark.parametrize("broken,message", [
    (TINY.replace("0 1 0.5", "0 one 0.5"), "expected 3 numbers"),
    (TINY.replace("0 1 2", "0 1 7"), "outside"),
    (TINY.split("# SHAPE")[0], "unexpected end of file"),
])
def test_malformed_file_names_the_problem(tmp_path, broken, message):
    p = tmp_path / "bad.wfm"
    p.write_text(broken)
    with pytest.raises(InputError, match=message):
        read_wfm(p)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_wfm(tmp_path / "none.wfm")


def test_standard_candide3_file():
    c = read_wfm(shared_path("candide3", "candide3.wfm"))
    assert c.vertices.shape == (113, 3)
    assert c.triangles.shape == (184, 3)
    assert c.shape_units.shape == (14, 113, 3)
    codes = {n.split()[0] for n in c.anim_names if n.startswith("AUV")}
    assert codes == {f"AUV{i}" for i in (0, 2, 3, 5, 6, 7, 8, 9, 10, 11, 14)}  # the AUVs Candide-3.1.6 defines
    jaw = c.anim_units[c.anim_index("AUV11")]
    assert jaw[10, 1] < 0  # jaw drop moves the chin down
    assert np.allclose(c.vertices[:, 0].mean(), 0, atol=1e-3)  # symmetric about x = 0
