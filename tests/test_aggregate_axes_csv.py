"""Reading the per-(scene, method) axes CSV, and its one-line errors."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.aggregate import read_axes_csv
from r360gpu.errors import InputError

HEADER = "scene,method,s_sem,s_geo,s_str\n"


def _write(tmp_path, text, name="axes.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_reads_grid_in_first_appearance_order_with_comments_and_quotes(tmp_path):
    path = _write(tmp_path, "# produced by hand\n\n" + HEADER +
                  '"Office, Chairs",B,0.1,0.2,0.3\n'
                  "Sofa,A,0.4,0.5,0.6\n"
                  '"Office, Chairs",A,0.7,0.8,0.9\n'
                  "  # indented comment\n"
                  "Sofa,B,1,0,0.5\n")
    cells = read_axes_csv(path)
    assert cells.scenes == ("Office, Chairs", "Sofa")
    assert cells.methods == ("B", "A")
    np.testing.assert_array_equal(cells.s_sem, [[0.1, 0.7], [1.0, 0.4]])
    np.testing.assert_array_equal(cells.s_str, [[0.3, 0.9], [0.5, 0.6]])
    assert cells.n_views is None and cells.iou_drop is None


def test_optional_columns_and_ignored_extras(tmp_path):
    path = _write(tmp_path, "method,scene,s_str,s_geo,s_sem,n_views,iou_drop,psnr\n"
                  "A,x,0.1,0.2,0.3,10,-0.25,17.2\nA,y,0.4,0.5,0.6,20,0.5,18\n")
    cells = read_axes_csv(path)
    np.testing.assert_array_equal(cells.n_views, [[10], [20]])
    np.testing.assert_array_equal(cells.iou_drop, [[-0.25], [0.5]])
    np.testing.assert_array_equal(cells.s_sem, [[0.3], [0.6]])


def test_utf8_bom_is_accepted(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes(("\ufeff" + HEADER + "x,A,0.1,0.2,0.3\n").encode("utf-8"))
    assert read_axes_csv(path).scenes == ("x",)


@pytest.mark.parametrize("text, fragment", [
    ("", "empty CSV"),
    ("# only a comment\n", "empty CSV"),
    (HEADER, "no data rows"),
    ("scene,method,s_sem,s_str\nx,A,0.1,0.2\n", "line 1: missing column(s) s_geo"),
    ("scene,method,s_sem,s_geo,s_str,s_sem\n", "column 's_sem' appears twice"),
    (HEADER + "x,A,0.1,0.2\n", "line 2: expected 5 fields, got 4"),
    (HEADER + "x,A,0.1,abc,0.3\n", "line 2, column s_geo: 'abc' is not a number"),
    (HEADER + "x,A,0.1,,0.3\n", "line 2, column s_geo: '' is not a number"),
    (HEADER + "x,A,nan,0.2,0.3\n", "line 2, column s_sem: 'nan' is not a finite number"),
    (HEADER + "x,A,0.1,0.2,1.2\n", "line 2, column s_str: 1.2 is outside [0, 1]"),
    (HEADER + "x,A,-0.1,0.2,0.3\n", "line 2, column s_sem: -0.1 is outside [0, 1]"),
    (HEADER + ",A,0.1,0.2,0.3\n", "line 2, column scene: empty name"),
    (HEADER + "x,A,0.1,0.2,0.3\n# c\nx,A,0.1,0.2,0.3\n",
     "line 4: duplicate row for (scene, method) = (x, A); first on line 2"),
    (HEADER + "x,A,0.1,0.2,0.3\nx,B,0.1,0.2,0.3\ny,A,0.1,0.2,0.3\n",
     "method 'B' has no row for scene(s) 'y'"),
    ("scene,method,s_sem,s_geo,s_str,n_views\nx,A,0.1,0.2,0.3,2.5\n",
     "line 2, column n_views: '2.5' is not a positive integer view count"),
    ("scene,method,s_sem,s_geo,s_str,n_views\nx,A,0.1,0.2,0.3,0\n", "column n_views: '0'"),
    ("scene,method,s_sem,s_geo,s_str,iou_drop\nx,A,0.1,0.2,0.3,1.5\n",
     "line 2, column iou_drop: 1.5 is outside [-1, 1]"),
])
def test_bad_csv_raises_one_line_input_error_naming_file(tmp_path, text, fragment):
    path = _write(tmp_path, text)
    with pytest.raises(InputError) as err:
        read_axes_csv(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ")
    assert fragment in message
    assert "\n" not in message


def test_unreadable_inputs(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_axes_csv(tmp_path / "missing.csv")
    with pytest.raises(InputError, match="directory"):
        read_axes_csv(tmp_path)
    bad = tmp_path / "latin1.csv"
    bad.write_bytes(HEADER.encode() + "Caf\xe9,A,0.1,0.2,0.3\n".encode("latin-1"))
    with pytest.raises(InputError, match="not UTF-8"):
        read_axes_csv(bad)
