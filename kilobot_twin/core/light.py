"""Light fields (what the projector shows) and the per-robot light-sensor response.

A field maps positions (m) and time (s) to a true intensity on the authors' 0-1024 scale.
The sensor turns that into an ADC reading with the robot's own gain, offset, noise and
saturation at 1023 (paper Fig. 8).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError, is_number
from . import libm, rng
from .constants import LIGHT_PEAK, LIGHT_READING_MAX


@dataclass(frozen=True)
class ConeField:
    """The authors' linear cone: ``peak * (1 - r / radius_m)`` clipped to [0, peak].

    With the authors' ``radius = 0.7071 * W`` (W the arena width) the light reaches 0 at the
    arena's corners.
    """

    center: tuple[float, float] = (0.0, 0.0)
    peak: float = LIGHT_PEAK
    radius_m: float = 0.7071 * 4.0
    kind: str = field(default="cone", init=False)

    def intensity(self, x, y, t_s=0.0):
        r = np.hypot(np.asarray(x) - self.center[0], np.asarray(y) - self.center[1])
        return np.clip(self.peak * (1.0 - r / self.radius_m), 0.0, self.peak)


@dataclass(frozen=True)
class GaussianField:
    """A Gaussian spot: ``peak * exp(-r^2 / (2 sigma_m^2))``."""

    center: tuple[float, float] = (0.0, 0.0)
    peak: float = LIGHT_PEAK
    sigma_m: float = 0.5
    kind: str = field(default="gaussian", init=False)

    def intensity(self, x, y, t_s=0.0):
        r2 = (np.asarray(x) - self.center[0]) ** 2 + (np.asarray(y) - self.center[1]) ** 2
        return self.peak * libm.exp(-0.5 * r2 / self.sigma_m**2)


@dataclass(frozen=True)
class UniformSweepField:
    """A uniform grey screen whose V-value ramps 0 -> 1 in a saw-tooth (paper Fig. 8a).

    ``ramps`` saw-teeth of ``period_s`` each, starting at ``start_s``; outside them V = 0.
    The intensity everywhere is ``peak * V(t)``.
    """

    period_s: float = 60.0
    ramps: int = 4
    peak: float = LIGHT_PEAK
    start_s: float = 0.0
    center: tuple[float, float] = (0.0, 0.0)
    kind: str = field(default="sweep", init=False)

    def v_value(self, t_s):
        t = np.asarray(t_s, dtype=np.float64) - self.start_s
        active = (t >= 0) & (t < self.ramps * self.period_s)
        return np.where(active, np.mod(t, self.period_s) / self.period_s, 0.0)

    def intensity(self, x, y, t_s=0.0):
        return np.broadcast_to(self.peak * self.v_value(t_s), np.broadcast(np.asarray(x), np.asarray(y)).shape)


@dataclass(frozen=True, eq=False)
class ImageField:
    """An image projected on the arena: ``image[row, col]`` in [0, 1] times ``peak``.

    ``extent_m = (xmin, xmax, ymin, ymax)``; row 0 is the top (largest y), as in a picture.
    Bilinear interpolation inside, 0 outside. ``path`` is the file the image was read from
    (absolute); documents carry it so that other processes (robot nodes) can load the same image.
    """

    image: np.ndarray
    extent_m: tuple[float, float, float, float] = (-2.0, 2.0, -2.0, 2.0)
    peak: float = LIGHT_PEAK
    center: tuple[float, float] = (0.0, 0.0)
    path: str = ""
    kind: str = field(default="image", init=False)

    def intensity(self, x, y, t_s=0.0):
        img = np.asarray(self.image, dtype=np.float64)
        h, w = img.shape
        xmin, xmax, ymin, ymax = self.extent_m
        fx = (np.asarray(x) - xmin) / (xmax - xmin) * w - 0.5
        fy = (ymax - np.asarray(y)) / (ymax - ymin) * h - 0.5
        inside = (fx >= -0.5) & (fx <= w - 0.5) & (fy >= -0.5) & (fy <= h - 0.5)
        fx = np.clip(fx, 0, w - 1)
        fy = np.clip(fy, 0, h - 1)
        x0 = np.minimum(np.floor(fx).astype(np.int64), w - 2 if w > 1 else 0)
        y0 = np.minimum(np.floor(fy).astype(np.int64), h - 2 if h > 1 else 0)
        x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
        ax, ay = fx - x0, fy - y0
        top = img[y0, x0] * (1 - ax) + img[y0, x1] * ax
        bot = img[y1, x0] * (1 - ax) + img[y1, x1] * ax
        return np.where(inside, self.peak * (top * (1 - ay) + bot * ay), 0.0)


LightField = ConeField | GaussianField | UniformSweepField | ImageField
_FIELDS = {"cone": ConeField, "gaussian": GaussianField, "sweep": UniformSweepField}


def field_from_dict(data: Mapping[str, Any], source: str = "", where: str = "light.") -> LightField:
    """Build a light field from ``{kind: cone, radius_m: 2.83, ...}`` with one-line errors."""
    if not isinstance(data, Mapping) or "kind" not in data:
        raise ConfigError(f"{where}kind", "missing", f"use one of {', '.join(_FIELDS)} or image", source)
    kind = data["kind"]
    args = {k: v for k, v in data.items() if k != "kind"}
    if kind == "image":
        path = args.pop("path", None)
        if path is None:
            raise ConfigError(f"{where}path", "missing for an image field", "give a .npy or .png path", source)
        p = _image_path(path, source)
        args["image"] = _load_image(p, f"{where}path", source)
        args["path"] = str(p.resolve())
        cls = ImageField
    elif kind in _FIELDS:
        cls = _FIELDS[kind]
    else:
        raise ConfigError(f"{where}kind", f"unknown light field {kind!r}", f"use one of {', '.join(_FIELDS)}, image", source)
    names = {f for f in cls.__dataclass_fields__ if f != "kind"}
    for k, v in args.items():
        if k not in names:
            raise ConfigError(f"{where}{k}", f"not a parameter of the {kind} field", f"use {', '.join(sorted(names))}", source)
        if k in ("center", "extent_m"):  # (a wrong length or a word was a traceback, .nan was taken)
            size, shape = (2, "[x, y]") if k == "center" else (4, "[xmin, xmax, ymin, ymax]")
            if not isinstance(v, (list, tuple)) or len(v) != size or not all(is_number(c) for c in v):
                raise ConfigError(f"{where}{k}", f"expected {shape} in metres, got {v!r}", f"write {k}: {shape}", source)
            if k == "extent_m" and not (v[0] < v[1] and v[2] < v[3]):
                raise ConfigError(f"{where}{k}", f"expected xmin < xmax and ymin < ymax, got {list(v)}",
                                  f"write {k}: {shape}", source)
            args[k] = tuple(float(c) for c in v)
        elif k not in ("image", "path"):
            if not is_number(v):
                raise ConfigError(f"{where}{k}", f"expected a number, got {v!r}", "write a plain number", source)
            if k in ("radius_m", "sigma_m", "period_s", "peak") and v <= 0:
                raise ConfigError(f"{where}{k}", f"must be positive, got {v}", "use a positive value", source)
    if "ramps" in args:
        args["ramps"] = int(args["ramps"])
    return cls(**args)


def field_to_dict(f: LightField) -> dict:
    """The field as a document. An image field is written by its ``path``: one built from an
    array alone has none, and a document of it cannot be loaded again (one-line error there)."""
    d = {k: v for k, v in asdict(f).items() if k not in ("image", "kind")}
    if d.get("path") == "":
        del d["path"]
    d = {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}
    return {"kind": f.kind, **d}


def _image_path(path, source):
    """An image path as written: relative to the document it is written in (``source``, when
    that is a file), else to the working directory."""
    from pathlib import Path

    p = Path(path).expanduser()
    if not p.is_absolute() and source and Path(source).is_file() and (Path(source).parent / p).is_file():
        p = Path(source).parent / p
    return p


def _load_image(p, where, source) -> np.ndarray:
    """The image at ``p`` (a path from :func:`_image_path`) as floats in [0, 1]."""
    if not p.is_file():
        raise ConfigError(where, f"image {p} not found", "check the path", source)
    try:  # (a file that is no image was a traceback from NumPy or Pillow)
        if p.suffix == ".npy":
            img = np.load(p)
        else:
            import matplotlib.image as mpimg

            img = mpimg.imread(p)
            if img.ndim == 3:
                img = img[..., :3].mean(axis=-1)
        img = np.asarray(img, dtype=np.float64)
    except (OSError, ValueError, TypeError, SyntaxError) as exc:  # (Pillow: SyntaxError for a bad PNG)
        raise ConfigError(where, f"{p} is not a readable image ({type(exc).__name__})",
                          "give a .npy array or a picture (.png) of the light", source) from None
    if img.ndim != 2 or min(img.shape) < 1 or not np.all(np.isfinite(img)) or img.min() < 0:
        raise ConfigError(where, f"{p} holds no 2-D image of finite intensities >= 0 (shape {img.shape})",
                          "give a .npy array of rows x columns, or a picture (.png)", source)
    if img.max() > 1.0:
        img = img / img.max()
    return img


@dataclass(frozen=True)
class SensorModel:
    """How the ambient-light sensor turns intensity into a reading (scenario-wide part).

    ``samples`` readings are averaged per measurement (the authors' controller uses 10).
    ``knee`` shapes the approach to the ceiling: 0 means a hard clip at ``ceiling``; p > 0
    uses the soft clip ``y / (1 + (y / ceiling)^p)^(1/p)``, which bends over smoothly like
    the measured curves of paper Fig. 8b (p = 6 matches them by eye).
    """

    ceiling: float = LIGHT_READING_MAX
    samples: int = 10
    knee: float = 0.0


def sensor_response(intensity, gain, offset, model: SensorModel = SensorModel()):
    """Noise-free reading for a true intensity, per robot (shapes broadcast)."""
    y = np.maximum(offset + gain * intensity, 0.0)
    if model.knee > 0:
        y = y / libm.power(1.0 + libm.power(y / model.ceiling, model.knee), 1.0 / model.knee)
    return np.minimum(y, model.ceiling)


def sense(intensity, gain, offset, noise_sd, keys, counter, model: SensorModel = SensorModel()):
    """One averaged light measurement per robot, in integer ADC counts (``counter``: the step's
    counter, or an array of them broadcast against ``keys``, for many steps at once).

    The mean of ``model.samples`` samples with per-sample noise ``noise_sd`` is drawn as one
    normal with sd ``noise_sd / sqrt(samples)`` (exact for Gaussian sample noise), then
    clipped to [0, ceiling] and truncated like the controller's integer average.
    """
    y = sensor_response(intensity, gain, offset, model)
    if np.any(noise_sd > 0):
        y = y + rng.normal(keys, counter) * (noise_sd / np.sqrt(model.samples))
    return np.floor(np.clip(y, 0.0, model.ceiling))


def raster(field, arena, pixels: int, t_s: float = 0.0):
    """``field``'s intensity on a ``pixels`` x ``pixels`` raster over ``arena`` (row 0 = top = +y,
    as in a picture; cell centres) and the raster's extent (x_min, x_max, y_min, y_max) in m."""
    xs = (np.arange(pixels) + 0.5) / pixels * arena.width_m - arena.width_m / 2
    ys = arena.height_m / 2 - (np.arange(pixels) + 0.5) / pixels * arena.height_m
    X, Y = np.meshgrid(xs, ys)
    extent = (-arena.width_m / 2, arena.width_m / 2, -arena.height_m / 2, arena.height_m / 2)
    return np.asarray(field.intensity(X, Y, t_s), dtype=np.float64), extent
