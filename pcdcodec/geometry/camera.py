"""Camera intrinsics, lens distortion, and their conversions.

:class:`CameraIntrinsics` holds the image size in pixels, the focal lengths and principal point
in pixels (zero skew) and, optionally, a lens distortion model with its coefficients:

* ``"none"``: the pinhole model Open3D's ``PinholeCameraIntrinsic`` uses;
* ``"plumb_bob"``: Brown-Conrady, ``(k1, k2, p1, p2, k3)`` (ROS and OpenCV order);
* ``"rational_polynomial"``: ``(k1, k2, p1, p2, k3, k4, k5, k6)``, OpenCV's rational model,
  which the Azure Kinect calibrates;
* ``"equidistant"``: Kannala-Brandt fisheye, ``(k1, k2, k3, k4)`` (OpenCV's ``fisheye``).

Distortion maps the normalised image coordinates ``(x, y) = (X / Z, Y / Z)`` of a point to the
distorted ones that the focal lengths and principal point turn into pixels, exactly as OpenCV's
``projectPoints`` and ``fisheye.projectPoints``. :meth:`CameraIntrinsics.project` and
:meth:`CameraIntrinsics.rays` go from points to pixels and from pixels to rays.

Intrinsics convert to and from Open3D (pinhole only), a 3 × 3 camera matrix ``K``, a ROS
``sensor_msgs/CameraInfo`` dict and a plain JSON dict. Open3D is imported only by
:meth:`CameraIntrinsics.to_open3d`. :func:`as_intrinsics` takes a camera in any form pcdcodec
accepts; :func:`read_intrinsics` reads the files datasets ship and :data:`CAMERA_PRESETS` holds
well-known dataset cameras, both from the plain data of :mod:`pcdcodec.geometry.dataset_cameras`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import operator
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError, InputTypeError

if TYPE_CHECKING:
    from .dataset_cameras import INTRINSICS_FILE_NAMES, find_intrinsics_file

    #: Named cameras (640×480) from the datasets' published values (``--camera NAME`` on the
    #: CLI), made on first use from :data:`pcdcodec.geometry.dataset_cameras.PUBLISHED_CAMERAS`.
    CAMERA_PRESETS: dict[str, CameraPreset]

__all__ = [
    "CAMERA_PRESETS",
    "DISTORTION_MODELS",
    "INTRINSICS_FILE_NAMES",
    "CameraIntrinsics",
    "CameraPreset",
    "as_intrinsics",
    "camera_preset",
    "find_intrinsics_file",
    "normalise_distortion",
    "read_intrinsics",
]

_DICT_KEYS = ("width", "height", "fx", "fy", "cx", "cy")
_DISTORTION_KEYS = ("distortion_model", "distortion")

#: Distortion models and their number of coefficients.
DISTORTION_MODELS: dict[str, int] = {
    "none": 0,
    "plumb_bob": 5,
    "rational_polynomial": 8,
    "equidistant": 4,
}
# Other names of the same models: ROS, librealsense, OpenCV, Azure Kinect.
_MODEL_ALIASES = {
    "": "none",
    "brown conrady": "plumb_bob",
    "brown_conrady": "plumb_bob",
    "radtan": "plumb_bob",
    "rational": "rational_polynomial",
    "kannala brandt4": "equidistant",
    "kannala_brandt": "equidistant",
    "fisheye": "equidistant",
}


def _as_size(value: Any, name: str) -> int:
    if isinstance(value, (bool, np.bool_)):
        raise InputTypeError(f"{name} must be an int (pixels), got {value!r}")
    try:
        size = operator.index(value)
    except TypeError:
        raise InputTypeError(
            f"{name} must be an int (pixels), got {type(value).__name__} {value!r}"
        ) from None
    if size <= 0:
        raise InputError(f"{name} must be a positive number of pixels, got {size}")
    return size


def _as_real(value: Any, name: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InputTypeError(
            f"{name} must be a real number (pixels), got {type(value).__name__} {value!r}"
        )
    real = float(value)
    if not math.isfinite(real):
        raise InputError(f"{name} must be finite, got {real!r}")
    return real


def normalise_distortion(model: Any, coefficients: Any) -> tuple[str, tuple[float, ...]]:
    """A distortion model's canonical name and its coefficients as a tuple of floats.

    Accepts the names of :data:`DISTORTION_MODELS` and their ROS / librealsense / OpenCV
    spellings (``"Brown Conrady"``, ``"Kannala Brandt4"``, ``"fisheye"``, ...). Brown-Conrady and
    rational coefficients that are all zero mean no distortion and give ``"none"``; a plumb_bob
    list of 4 is completed with ``k3 = 0``. Raises :class:`~pcdcodec.InputError` for an unknown
    model, a wrong number of coefficients or a coefficient that is not finite.
    """
    if not isinstance(model, str):
        raise InputTypeError(f"distortion_model must be a string, got {type(model).__name__}")
    name = model.strip()
    name = _MODEL_ALIASES.get(name.lower(), name.lower())
    if name not in DISTORTION_MODELS:
        raise InputError(
            f"unknown distortion model {model!r}; expected one of {list(DISTORTION_MODELS)}"
        )
    try:
        coeffs = np.asarray([] if coefficients is None else coefficients, np.float64).ravel()
    except (TypeError, ValueError):
        raise InputError(f"distortion coefficients must be numbers, got {coefficients!r}") from None
    if not np.isfinite(coeffs).all():
        raise InputError(f"distortion coefficients must be finite, got {coeffs.tolist()}")
    if name in ("plumb_bob", "rational_polynomial", "none") and not np.any(coeffs):
        return "none", ()
    if name == "plumb_bob" and coeffs.size == 4:
        coeffs = np.append(coeffs, 0.0)
    if name == "rational_polynomial" and coeffs.size == 5:
        coeffs = np.append(coeffs, [0.0, 0.0, 0.0])
    expected = DISTORTION_MODELS[name]
    if coeffs.size != expected:
        raise InputError(
            f"distortion model {name!r} takes {expected} coefficients, got {coeffs.size}: "
            f"{coeffs.tolist()}"
        )
    return name, tuple(float(c) for c in coeffs)


@dataclass(frozen=True)
class CameraIntrinsics:
    """Intrinsics of a camera, all in pixels, with an optional lens distortion model.

    ``width`` and ``height`` are the image size, ``fx`` and ``fy`` the focal lengths and
    ``(cx, cy)`` the principal point, with pixel ``(u, v) = (0, 0)`` the centre of the top-left
    pixel (the Open3D and OpenCV convention). Values are normalised to ``int`` and ``float``.
    ``distortion_model`` and ``distortion`` name a model of :data:`DISTORTION_MODELS` and its
    coefficients (see the module docstring); the default is an undistorted pinhole camera.

    Raises :class:`~pcdcodec.InputTypeError` for a non-numeric value and
    :class:`~pcdcodec.InputError` for a non-positive size, a focal length that is not positive and
    finite, a principal point outside ``[0, width] × [0, height]``, or an unknown distortion
    model or wrong number of coefficients.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion_model: str = "none"
    distortion: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        width = _as_size(self.width, "width")
        height = _as_size(self.height, "height")
        values = {name: _as_real(getattr(self, name), name) for name in ("fx", "fy", "cx", "cy")}
        for name in ("fx", "fy"):
            if values[name] <= 0:
                raise InputError(f"{name} must be a positive focal length, got {values[name]!r}")
        if not 0 <= values["cx"] <= width:
            raise InputError(
                f"cx must lie in the image, 0 <= cx <= width={width}, got {values['cx']!r}"
            )
        if not 0 <= values["cy"] <= height:
            raise InputError(
                f"cy must lie in the image, 0 <= cy <= height={height}, got {values['cy']!r}"
            )
        # The dataclass is frozen; normalise numpy scalars and ints to plain int/float.
        object.__setattr__(self, "width", width)
        object.__setattr__(self, "height", height)
        for name, value in values.items():
            object.__setattr__(self, name, value)
        model, coeffs = normalise_distortion(self.distortion_model, self.distortion)
        object.__setattr__(self, "distortion_model", model)
        object.__setattr__(self, "distortion", coeffs)

    @property
    def has_distortion(self) -> bool:
        """Whether the lens model is anything but the plain pinhole."""
        return self.distortion_model != "none"

    def pinhole(self) -> CameraIntrinsics:
        """The same camera without its distortion model."""
        return CameraIntrinsics(self.width, self.height, self.fx, self.fy, self.cx, self.cy)

    # -- projection -------------------------------------------------------------------

    def distort(
        self, x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Distorted normalised coordinates of the undistorted ones ``(x, y) = (X/Z, Y/Z)``."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        model, d = self.distortion_model, self.distortion
        if model == "none":
            return x, y
        r2 = x * x + y * y
        if model == "equidistant":
            r = np.sqrt(r2)
            theta = np.arctan(r)
            t2 = theta * theta
            theta_d = theta * (1 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))))
            with np.errstate(invalid="ignore", divide="ignore"):
                scale = np.where(r > 1e-12, theta_d / r, 1.0)
            return x * scale, y * scale
        k1, k2, p1, p2, k3 = d[:5]
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        if model == "rational_polynomial":
            k4, k5, k6 = d[5:8]
            radial = radial / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        xy = x * y
        xd = x * radial + 2 * p1 * xy + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * xy
        return xd, yd

    def undistort(
        self, xd: npt.NDArray[np.float64], yd: npt.NDArray[np.float64], *, tolerance: float = 1e-9
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Undistorted normalised coordinates of distorted ones: the inverse of :meth:`distort`.

        Solved by Newton's method per point. Where it does not converge to within
        ``tolerance`` (normalised units; 1e-9 is about a millionth of a pixel), for instance
        outside the region where the lens model is one-to-one, the result is NaN.
        """
        xd = np.asarray(xd, dtype=np.float64)
        yd = np.asarray(yd, dtype=np.float64)
        if not self.has_distortion:
            return xd.copy(), yd.copy()
        x, y = xd.copy(), yd.copy()
        h = 1e-7
        for _ in range(30):
            fx, fy = self.distort(x, y)
            ex, ey = fx - xd, fy - yd
            if float(np.nanmax(np.abs(ex) + np.abs(ey), initial=0.0)) < tolerance * 1e-3:
                break
            ax, ay = self.distort(x + h, y)
            bx, by = self.distort(x, y + h)
            j11, j21 = (ax - fx) / h, (ay - fy) / h
            j12, j22 = (bx - fx) / h, (by - fy) / h
            det = j11 * j22 - j12 * j21
            with np.errstate(invalid="ignore", divide="ignore"):
                x = x - (j22 * ex - j12 * ey) / det
                y = y - (j11 * ey - j21 * ex) / det
        fx, fy = self.distort(x, y)
        with np.errstate(invalid="ignore"):
            bad = ~(np.abs(fx - xd) + np.abs(fy - yd) < tolerance)
        x[bad] = np.nan
        y[bad] = np.nan
        return x, y

    def project(
        self, points: Any
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.bool_]]:
        """Pixel coordinates ``(u, v)`` of N × 3 points (metres, camera frame), and which are
        in front of the camera (``z > 0`` and finite); other points get NaN coordinates."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        z = pts[:, 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            front = np.isfinite(pts).all(axis=1) & (z > 0)
            x = np.where(front, pts[:, 0] / z, np.nan)
            y = np.where(front, pts[:, 1] / z, np.nan)
        xd, yd = self.distort(x, y)
        return xd * self.fx + self.cx, yd * self.fy + self.cy, front

    def rays(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """For every pixel, the ``(X / Z, Y / Z)`` of the points it sees: two H × W arrays.

        Without distortion these are ``(u - cx) / fx`` and ``(v - cy) / fy``. With distortion
        each pixel is undistorted (NaN where the model cannot be inverted there).
        """
        u = (np.arange(self.width, dtype=np.float64) - self.cx) / self.fx
        v = (np.arange(self.height, dtype=np.float64) - self.cy) / self.fy
        xd, yd = np.meshgrid(u, v)
        return self.undistort(xd, yd)

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)``: the shape of a depth image taken with this camera."""
        return (self.height, self.width)

    # -- camera matrix -----------------------------------------------------------------

    @property
    def K(self) -> npt.NDArray[np.float64]:  # noqa: N802  (the usual name of the camera matrix)
        """The camera matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` (new 3 × 3 float64)."""
        return np.array(
            [[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]], dtype=np.float64
        )

    @classmethod
    def from_K(cls, K: Any, width: int, height: int) -> CameraIntrinsics:  # noqa: N802, N803
        """Build intrinsics from a 3 × 3 camera matrix ``K`` and the image size in pixels.

        Raises :class:`~pcdcodec.InputError` when ``K`` is not 3 × 3, is not finite, has a
        non-zero skew ``K[0, 1]`` or ``K[1, 0]``, or its last row is not ``[0, 0, 1]``.
        """
        try:
            k = np.asarray(K, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputTypeError(f"K must be a 3x3 array of numbers, got {K!r}") from None
        if k.shape != (3, 3):
            raise InputError(f"K must have shape (3, 3), got {k.shape}")
        if not np.isfinite(k).all():
            raise InputError(f"K must be finite, got {k.tolist()}")
        if k[0, 1] != 0 or k[1, 0] != 0:
            raise InputError(
                "K must have zero skew (K[0, 1] == K[1, 0] == 0), got "
                f"K[0, 1]={float(k[0, 1])!r}, K[1, 0]={float(k[1, 0])!r}"
            )
        if k[2].tolist() != [0.0, 0.0, 1.0]:
            raise InputError(f"the last row of K must be [0, 0, 1], got {k[2].tolist()}")
        return cls(width, height, k[0, 0], k[1, 1], k[0, 2], k[1, 2])

    # -- Open3D ------------------------------------------------------------------------

    def to_open3d(self) -> Any:
        """An ``open3d.camera.PinholeCameraIntrinsic`` with these values (imports open3d).

        Open3D's pinhole model has no distortion: a distorted camera raises
        :class:`~pcdcodec.InputError` (use :meth:`pinhole` to drop it on purpose).
        """
        if self.has_distortion:
            raise InputError(
                f"Open3D's PinholeCameraIntrinsic has no distortion, and this camera has "
                f"{self.distortion_model} distortion {list(self.distortion)}; call .pinhole() "
                "first to drop it on purpose"
            )
        import open3d as o3d

        return o3d.camera.PinholeCameraIntrinsic(
            self.width, self.height, self.fx, self.fy, self.cx, self.cy
        )

    @classmethod
    def from_open3d(cls, pinhole: Any) -> CameraIntrinsics:
        """Build intrinsics from an ``open3d.camera.PinholeCameraIntrinsic``.

        Raises :class:`~pcdcodec.InputTypeError` for another kind of object and
        :class:`~pcdcodec.InputError` for a non-zero skew or invalid values.
        """
        try:
            width, height, matrix = pinhole.width, pinhole.height, pinhole.intrinsic_matrix
        except AttributeError:
            raise InputTypeError(
                "pinhole must be an open3d.camera.PinholeCameraIntrinsic, "
                f"got {type(pinhole).__name__}"
            ) from None
        return cls.from_K(matrix, width, height)

    # -- ROS CameraInfo -----------------------------------------------------------------

    def to_camera_info(self) -> dict[str, Any]:
        """A dict shaped like ROS ``sensor_msgs/CameraInfo`` (ROS 1 upper-case field names).

        Holds ``width``, ``height``, ``distortion_model`` (``"plumb_bob"`` with five zeros ``D``
        for an undistorted camera, else the model and its coefficients), ``K`` (9 floats,
        row-major), ``R`` (identity, 9 floats) and ``P`` (12 floats, row-major).
        """
        fx, fy, cx, cy = self.fx, self.fy, self.cx, self.cy
        model = "plumb_bob" if self.distortion_model == "none" else self.distortion_model
        return {
            "width": self.width,
            "height": self.height,
            "distortion_model": model,
            "D": list(self.distortion) if self.has_distortion else [0.0] * 5,
            "K": [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            "P": [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        }

    @classmethod
    def from_camera_info(cls, info: Mapping[str, Any]) -> CameraIntrinsics:
        """Build intrinsics from a ROS ``sensor_msgs/CameraInfo``-style dict.

        Reads ``width``, ``height``, ``K`` (9 floats, row-major), ``distortion_model`` and ``D``
        (both optional); the ROS 2 lower-case ``k`` and ``d`` are accepted too. Distortion
        models are those of :data:`DISTORTION_MODELS` under their ROS or librealsense names; an
        unknown model with a non-zero ``D`` raises :class:`~pcdcodec.InputError` rather than
        giving points in the wrong place. A missing key raises :class:`~pcdcodec.InputError`
        naming it.
        """
        if not isinstance(info, Mapping):
            raise InputTypeError(f"camera info must be a mapping, got {type(info).__name__}")

        def get(key: str, required: bool = True) -> Any:
            for k in (key, key.lower()):
                if k in info:
                    return info[k]
            if required:
                raise InputError(
                    f"camera info is missing the key {key!r}; it has keys {sorted(info)}"
                )
            return None

        width, height, k = get("width"), get("height"), get("K")
        if isinstance(k, (str, bytes)) or not isinstance(k, (Sequence, np.ndarray)) or len(k) != 9:
            raise InputError(f"camera info K must be a sequence of 9 numbers, got {k!r}")
        d = get("D", required=False)
        try:
            distortion = np.asarray([] if d is None else d, dtype=np.float64).ravel()
        except (TypeError, ValueError):
            raise InputError(f"camera info D must be a sequence of numbers, got {d!r}") from None
        model = get("distortion_model", required=False) or "plumb_bob"
        if not np.any(distortion != 0):
            model = "none"
        try:
            name, coeffs = normalise_distortion(model, distortion)
        except InputError as exc:
            raise InputError(f"camera info has distortion D={distortion.tolist()}: {exc}") from None
        try:
            matrix = np.reshape(np.asarray(k, dtype=np.float64), (3, 3))
        except (TypeError, ValueError):
            raise InputError(f"camera info K must be 9 numbers, got {k!r}") from None
        base = cls.from_K(matrix, width, height)
        return dataclasses.replace(base, distortion_model=name, distortion=coeffs)

    # -- plain dict ---------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """A JSON-serialisable dict with the keys ``width, height, fx, fy, cx, cy``, and
        ``distortion_model`` and ``distortion`` (a list) for a distorted camera only."""
        out: dict[str, Any] = {name: getattr(self, name) for name in _DICT_KEYS}
        if self.has_distortion:
            out["distortion_model"] = self.distortion_model
            out["distortion"] = list(self.distortion)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> CameraIntrinsics:
        """Build intrinsics from a dict made by :meth:`to_dict`.

        Raises :class:`~pcdcodec.InputError` for a missing or an unknown key, naming it.
        """
        if not isinstance(data, Mapping):
            raise InputTypeError(f"intrinsics dict must be a mapping, got {type(data).__name__}")
        missing = [k for k in _DICT_KEYS if k not in data]
        if missing:
            raise InputError(
                f"intrinsics dict is missing the key {missing[0]!r}; expected keys "
                f"{list(_DICT_KEYS)}"
            )
        unknown = sorted(str(k) for k in data if k not in _DICT_KEYS + _DISTORTION_KEYS)
        if unknown:
            raise InputError(
                f"intrinsics dict has an unknown key {unknown[0]!r}; expected keys "
                f"{list(_DICT_KEYS)} and optionally {list(_DISTORTION_KEYS)}"
            )
        extra = {k: data[k] for k in _DISTORTION_KEYS if k in data}
        if "distortion" in extra:
            extra["distortion"] = tuple(extra["distortion"])
        return cls(**{k: data[k] for k in _DICT_KEYS}, **extra)


# -- presets ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CameraPreset:
    """A dataset camera's published intrinsics, and the depth scale the dataset fixes."""

    name: str
    intrinsics: CameraIntrinsics
    depth_scale: float | None
    source: str


@functools.cache
def _presets() -> dict[str, CameraPreset]:
    from .dataset_cameras import PUBLISHED_CAMERAS

    return {
        name: CameraPreset(name, CameraIntrinsics(640, 480, *fxy), scale, source)
        for name, fxy, scale, source in PUBLISHED_CAMERAS
    }


def camera_preset(name: str) -> CameraPreset:
    """The preset called ``name`` (see :data:`CAMERA_PRESETS`); an unknown name raises
    :class:`~pcdcodec.InputError` listing the known ones."""
    presets = _presets()
    try:
        return presets[name]
    except KeyError:
        raise InputError(f"unknown camera {name!r}; known cameras: {', '.join(presets)}") from None


# -- coercion and files ------------------------------------------------------------------------


def as_intrinsics(
    value: Any, what: str | None = None, width: int | None = None, height: int | None = None
) -> CameraIntrinsics:
    """A :class:`CameraIntrinsics` from any of the ways pcdcodec takes a camera.

    ``value`` is a :class:`CameraIntrinsics` (returned as it is), a mapping with the keys of
    :meth:`CameraIntrinsics.from_dict` (``camera.json``'s), the path of an intrinsics file
    (:func:`read_intrinsics`) or an ``open3d.camera.PinholeCameraIntrinsic``. ``width`` and
    ``height`` fill in an image size a mapping or a file does not give.

    ``what`` names the value in errors (an argument, or the file a mapping came from): errors in
    a mapping's values are prefixed with it. Raises :class:`~pcdcodec.InputTypeError` for any
    other kind of value and :class:`~pcdcodec.InputError` for invalid values.
    """
    if isinstance(value, CameraIntrinsics):
        return value
    if isinstance(value, Mapping):
        size = {"width": width, "height": height}
        data = {**{k: v for k, v in size.items() if v is not None}, **value}
        try:
            return CameraIntrinsics.from_dict(data)
        except InputError as exc:
            if what is None:
                raise
            raise type(exc)(f"{what}: {exc}") from None
    if isinstance(value, (str, os.PathLike)):
        return read_intrinsics(value, width, height)
    if type(value).__name__ == "PinholeCameraIntrinsic":
        return CameraIntrinsics.from_open3d(value)
    raise InputTypeError(
        f"{what or 'intrinsics'} must be a CameraIntrinsics, a dict, an intrinsics file or an "
        f"Open3D PinholeCameraIntrinsic, got {type(value).__name__}"
    )


def read_intrinsics(
    path: str | os.PathLike[str], width: int | None = None, height: int | None = None
) -> CameraIntrinsics:
    """Camera intrinsics from a file datasets ship with.

    Read by content: a 3×3 camera matrix ``K`` as text (``intrinsics.K.txt``,
    ``camera-intrinsics.txt``; the image size then comes from ``width``/``height``), a ROS
    ``camera_calibration`` YAML (``image_width``, ``camera_matrix``, ...), a
    ``sensor_msgs/CameraInfo`` dump (``K``), an Open3D ``PinholeCameraIntrinsic`` JSON
    (``intrinsic_matrix``, column-major) or pcdcodec's ``camera.json``
    (:mod:`pcdcodec.geometry.dataset_cameras`). ``width`` and ``height`` fill in a size the
    file does not give. Raises :class:`~pcdcodec.InputError` for a missing or unreadable file,
    naming it and what was expected.
    """
    from .dataset_cameras import describe_intrinsics_file

    method, args = describe_intrinsics_file(path, width, height)
    camera: CameraIntrinsics = getattr(CameraIntrinsics, method)(*args)
    return camera


def __getattr__(name: str) -> Any:
    # What datasets publish is plain data in another module, loaded on first use.
    if name == "CAMERA_PRESETS":
        return _presets()
    if name in ("INTRINSICS_FILE_NAMES", "find_intrinsics_file"):
        from . import dataset_cameras

        return getattr(dataset_cameras, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
