"""CameraIntrinsics: validation and its conversions (Open3D, K, ROS CameraInfo, dict)."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pytest

from pcdcodec.errors import InputError, InputTypeError, PcdcodecError
from pcdcodec.geometry.camera import CameraIntrinsics

TUM = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
# Every value distinct, so a swapped field cannot go unnoticed.
ODD = CameraIntrinsics(1280, 720, 911.25, 909.5, 641.75, 358.125)


@pytest.fixture(params=[TUM, ODD], ids=["tum", "odd"])
def intr(request: pytest.FixtureRequest) -> CameraIntrinsics:
    value: CameraIntrinsics = request.param
    return value


def test_fields_and_shape() -> None:
    assert (ODD.width, ODD.height, ODD.fx, ODD.fy, ODD.cx, ODD.cy) == (
        1280,
        720,
        911.25,
        909.5,
        641.75,
        358.125,
    )
    assert ODD.shape == (720, 1280)


def test_numpy_scalars_are_normalised() -> None:
    c = CameraIntrinsics(np.int64(640), np.uint16(480), np.float32(525), 525, np.int32(319), 239.5)
    assert type(c.width) is int
    assert type(c.height) is int
    assert all(type(getattr(c, k)) is float for k in ("fx", "fy", "cx", "cy"))
    assert c == CameraIntrinsics(640, 480, 525.0, 525.0, 319.0, 239.5)


def test_frozen_and_hashable() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        TUM.fx = 1.0  # type: ignore[misc]
    assert len({TUM, CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5), ODD}) == 2


def test_principal_point_on_the_border_is_allowed() -> None:
    c = CameraIntrinsics(640, 480, 500.0, 500.0, 0.0, 480.0)
    assert (c.cx, c.cy) == (0.0, 480.0)


@pytest.mark.parametrize(
    ("kwargs", "error", "fragment"),
    [
        ({"width": 0}, InputError, "width must be a positive number of pixels, got 0"),
        ({"height": -5}, InputError, "height must be a positive number of pixels, got -5"),
        ({"width": 640.0}, InputTypeError, "width must be an int"),
        ({"width": True}, InputTypeError, "width must be an int (pixels), got True"),
        ({"height": "480"}, InputTypeError, "'480'"),
        ({"fx": 0.0}, InputError, "fx must be a positive focal length, got 0.0"),
        ({"fy": -525.0}, InputError, "fy must be a positive focal length, got -525.0"),
        ({"fx": math.nan}, InputError, "fx must be finite, got nan"),
        ({"fy": math.inf}, InputError, "fy must be finite, got inf"),
        ({"fx": "525"}, InputTypeError, "fx must be a real number"),
        ({"cx": -0.5}, InputError, "0 <= cx <= width=640, got -0.5"),
        ({"cx": 640.5}, InputError, "got 640.5"),
        ({"cy": 480.25}, InputError, "0 <= cy <= height=480, got 480.25"),
        ({"cy": math.nan}, InputError, "cy must be finite"),
    ],
)
def test_validation(kwargs: dict[str, object], error: type[Exception], fragment: str) -> None:
    args = {**TUM.to_dict(), **kwargs}
    with pytest.raises(error) as info:
        CameraIntrinsics(**args)
    assert fragment in str(info.value)
    assert isinstance(info.value, PcdcodecError)


# -- Open3D -------------------------------------------------------------------------------


def test_open3d_round_trip(intr: CameraIntrinsics) -> None:
    pinhole = intr.to_open3d()
    assert (pinhole.width, pinhole.height) == (intr.width, intr.height)
    assert pinhole.get_focal_length() == (intr.fx, intr.fy)
    assert pinhole.get_principal_point() == (intr.cx, intr.cy)
    np.testing.assert_array_equal(pinhole.intrinsic_matrix, intr.K)
    assert CameraIntrinsics.from_open3d(pinhole) == intr


def test_from_open3d_rejects_other_objects() -> None:
    with pytest.raises(InputTypeError, match="PinholeCameraIntrinsic, got dict"):
        CameraIntrinsics.from_open3d({"width": 640})


def test_from_open3d_rejects_skew() -> None:
    import open3d as o3d

    pinhole = o3d.camera.PinholeCameraIntrinsic()
    pinhole.set_intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
    matrix = np.array(pinhole.intrinsic_matrix)
    matrix[0, 1] = 2.0
    pinhole.intrinsic_matrix = matrix
    with pytest.raises(InputError, match=r"zero skew .*K\[0, 1\]=2\.0"):
        CameraIntrinsics.from_open3d(pinhole)


# -- K ------------------------------------------------------------------------------------


def test_K_values_and_round_trip(intr: CameraIntrinsics) -> None:  # noqa: N802
    k = intr.K
    assert k.dtype == np.float64
    assert k.shape == (3, 3)
    expected = [[intr.fx, 0, intr.cx], [0, intr.fy, intr.cy], [0, 0, 1]]
    np.testing.assert_array_equal(k, expected)
    assert CameraIntrinsics.from_K(k, intr.width, intr.height) == intr
    assert CameraIntrinsics.from_K(k.tolist(), intr.width, intr.height) == intr


def test_K_is_a_fresh_array() -> None:  # noqa: N802
    k = TUM.K
    k[0, 0] = 1.0
    assert TUM.K[0, 0] == 525.0


@pytest.mark.parametrize(
    ("matrix", "fragment"),
    [
        (np.eye(4), "K must have shape (3, 3), got (4, 4)"),
        (np.zeros(9), "K must have shape (3, 3), got (9,)"),
        ([[525, 0.5, 319.5], [0, 525, 239.5], [0, 0, 1]], "K[0, 1]=0.5"),
        ([[525, 0, 319.5], [3, 525, 239.5], [0, 0, 1]], "K[1, 0]=3.0"),
        ([[525, 0, 319.5], [0, 525, 239.5], [0, 0, 2]], "last row of K must be [0, 0, 1], got"),
        ([[525, 0, 319.5], [0, 525, 239.5], [0.1, 0, 1]], "[0.1, 0.0, 1.0]"),
        ([[np.nan, 0, 319.5], [0, 525, 239.5], [0, 0, 1]], "K must be finite"),
    ],
)
def test_from_K_errors(matrix: object, fragment: str) -> None:  # noqa: N802
    with pytest.raises(InputError) as info:
        CameraIntrinsics.from_K(matrix, 640, 480)
    assert fragment in str(info.value)


def test_from_K_rejects_non_numbers() -> None:  # noqa: N802
    with pytest.raises(InputTypeError, match="3x3 array of numbers"):
        CameraIntrinsics.from_K([["a", "b", "c"]] * 3, 640, 480)


def test_from_K_validates_the_values() -> None:  # noqa: N802
    k = TUM.K
    k[0, 2] = 700.0  # principal point right of the image
    with pytest.raises(InputError, match=r"got 700\.0"):
        CameraIntrinsics.from_K(k, 640, 480)


# -- ROS CameraInfo -------------------------------------------------------------------------


def test_camera_info_layout() -> None:
    info = ODD.to_camera_info()
    assert info["width"] == 1280
    assert info["height"] == 720
    assert info["distortion_model"] == "plumb_bob"
    assert info["D"] == [0.0] * 5
    assert info["K"] == [911.25, 0.0, 641.75, 0.0, 909.5, 358.125, 0.0, 0.0, 1.0]
    assert info["R"] == [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    assert info["P"] == [911.25, 0.0, 641.75, 0.0, 0.0, 909.5, 358.125, 0.0, 0.0, 0.0, 1.0, 0.0]
    # Plain JSON values only.
    assert json.loads(json.dumps(info)) == info


def test_camera_info_round_trip(intr: CameraIntrinsics) -> None:
    assert CameraIntrinsics.from_camera_info(intr.to_camera_info()) == intr


def test_camera_info_ros2_lower_case_keys() -> None:
    info = {k.lower(): v for k, v in ODD.to_camera_info().items()}
    assert CameraIntrinsics.from_camera_info(info) == ODD


def test_camera_info_without_distortion_key() -> None:
    info = {"width": 640, "height": 480, "K": TUM.to_camera_info()["K"]}
    assert CameraIntrinsics.from_camera_info(info) == TUM


@pytest.mark.parametrize("key", ["width", "height", "K"])
def test_camera_info_missing_key(key: str) -> None:
    info = TUM.to_camera_info()
    del info[key]
    with pytest.raises(InputError, match=f"missing the key '{key}'"):
        CameraIntrinsics.from_camera_info(info)


def test_camera_info_bad_values() -> None:
    info = TUM.to_camera_info()
    info["K"] = [525.0, 0.0, 319.5]
    with pytest.raises(InputError, match="K must be a sequence of 9 numbers"):
        CameraIntrinsics.from_camera_info(info)
    info = TUM.to_camera_info()
    info["D"] = [0.1, 0.0, 0.0, 0.0, 0.0]
    info["distortion_model"] = "mystery_lens"
    with pytest.raises(InputError, match=r"distortion D=\[0\.1, 0\.0.*'mystery_lens'"):
        CameraIntrinsics.from_camera_info(info)
    info["distortion_model"] = "plumb_bob"
    info["D"] = [0.1, 0.2]
    with pytest.raises(InputError, match="'plumb_bob' takes 5 coefficients, got 2"):
        CameraIntrinsics.from_camera_info(info)
    with pytest.raises(InputTypeError, match="must be a mapping, got list"):
        CameraIntrinsics.from_camera_info([1, 2, 3])  # type: ignore[arg-type]


# -- dict -----------------------------------------------------------------------------------


def test_dict_round_trip_through_json(intr: CameraIntrinsics) -> None:
    d = intr.to_dict()
    assert list(d) == ["width", "height", "fx", "fy", "cx", "cy"]
    assert CameraIntrinsics.from_dict(json.loads(json.dumps(d))) == intr


def test_from_dict_errors() -> None:
    d = TUM.to_dict()
    del d["cy"]
    with pytest.raises(InputError, match="missing the key 'cy'"):
        CameraIntrinsics.from_dict(d)
    with pytest.raises(InputError, match="unknown key 'skew'"):
        CameraIntrinsics.from_dict({**TUM.to_dict(), "skew": 0.0})
    with pytest.raises(InputError, match=r"fx must be a positive focal length, got -1\.0"):
        CameraIntrinsics.from_dict({**TUM.to_dict(), "fx": -1.0})


def test_importing_does_not_import_heavy_backends() -> None:
    code = (
        "import sys, pcdcodec, pcdcodec.geometry.camera, pcdcodec.geometry.projector\n"
        "heavy = sorted(m for m in ('open3d', 'av', 'cv2') if m in sys.modules)\n"
        "print(','.join(heavy))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == ""


def test_docs_list_every_preset_and_the_readme_uses_the_samples_camera() -> None:
    import json
    import re
    from pathlib import Path

    from pcdcodec.datasets import sample_dir
    from pcdcodec.geometry.camera import CAMERA_PRESETS

    root = Path(__file__).resolve().parents[1]
    ingest = (root / "docs" / "ingest.md").read_text()
    for name, preset in CAMERA_PRESETS.items():
        k = preset.intrinsics
        row = next((line for line in ingest.splitlines() if line.startswith(f"| `{name}` |")), "")
        assert row, f"docs/ingest.md does not list the preset {name}"
        cells = [c.strip() for c in row.split("|")[2:7]]
        assert [float(c) for c in cells[:4]] == [k.fx, k.fy, k.cx, k.cy], name
        assert float(cells[4]) == preset.depth_scale, name
    # The README's TUM example names the camera the bundled TUM sample records.
    readme = (root / "README.md").read_text()
    named = re.findall(r"encode path/to/tum_sequence .*?--camera (\S+)", readme)
    assert named
    sample = json.loads((sample_dir() / "camera.json").read_text())
    for name in named:
        k = CAMERA_PRESETS[name].intrinsics
        assert (k.fx, k.fy, k.cx, k.cy) == tuple(sample[c] for c in ("fx", "fy", "cx", "cy"))


# -- as_intrinsics: one coercion for every way a camera is given ------------------------------


def test_as_intrinsics_takes_every_form_of_a_camera(tmp_path: Path) -> None:
    from pcdcodec.geometry.camera import as_intrinsics

    assert as_intrinsics(TUM) is TUM
    # A mapping with camera.json's keys; the size fills in what it leaves out, it never wins.
    values = {k: getattr(ODD, k) for k in ("fx", "fy", "cx", "cy")}
    assert as_intrinsics(values, width=1280, height=720) == ODD
    assert as_intrinsics(ODD.to_dict(), width=1, height=1) == ODD
    assert as_intrinsics(MappingProxyType(ODD.to_dict())) == ODD
    # An intrinsics file, by path or str; a bare K takes the size given.
    (tmp_path / "camera.json").write_text(json.dumps(ODD.to_dict()))
    assert as_intrinsics(tmp_path / "camera.json") == ODD
    (tmp_path / "K.txt").write_text("525 0 319.5\n0 525 239.5\n0 0 1\n")
    assert as_intrinsics(str(tmp_path / "K.txt"), width=640, height=480) == TUM
    with pytest.raises(InputError, match="without the image size"):
        as_intrinsics(tmp_path / "K.txt")


def test_as_intrinsics_takes_an_open3d_pinhole() -> None:
    o3d = pytest.importorskip("open3d")
    from pcdcodec.geometry.camera import as_intrinsics

    pinhole = o3d.camera.PinholeCameraIntrinsic(640, 480, 525.0, 525.0, 319.5, 239.5)
    assert as_intrinsics(pinhole) == TUM


def test_as_intrinsics_names_what_was_wrong() -> None:
    from pcdcodec.geometry.camera import as_intrinsics

    # Without ``what`` a mapping's errors are the constructor's own; with it, prefixed.
    with pytest.raises(InputError, match=r"^intrinsics dict is missing the key 'fx'"):
        as_intrinsics({"fy": 1.0, "cx": 0.0, "cy": 0.0}, width=4, height=4)
    with pytest.raises(InputError, match=r"^'camera.json' color: intrinsics dict is missing"):
        as_intrinsics({"fy": 1.0}, "'camera.json' color", 4, 4)
    with pytest.raises(InputTypeError, match=r"^color_intrinsics: width must be an int"):
        as_intrinsics({"fx": 1, "fy": 1, "cx": 0, "cy": 0, "width": "4"}, "color_intrinsics", 4, 4)
    with pytest.raises(
        InputTypeError,
        match=r"^intrinsics must be a CameraIntrinsics, a dict, an intrinsics file or an Open3D "
        r"PinholeCameraIntrinsic, got int$",
    ):
        as_intrinsics(5)
    with pytest.raises(InputTypeError, match=r"^color_intrinsics must be .* got list$"):
        as_intrinsics([525.0, 525.0, 319.5, 239.5], "color_intrinsics")


def test_importing_leaves_the_open3d_conversions_and_dataset_cameras_unloaded() -> None:
    code = (
        "import sys, numpy, pcdcodec\n"
        "p = pcdcodec.Projector(pcdcodec.CameraIntrinsics(4, 3, 2.0, 2.0, 2.0, 1.5))\n"
        "p.to_points(numpy.ones((3, 4), numpy.uint16))\n"
        "names = ('pcdcodec.geometry.open3d', 'pcdcodec.geometry.dataset_cameras')\n"
        "print(','.join(m for m in names if m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == ""
