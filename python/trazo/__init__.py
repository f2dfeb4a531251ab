"""trazo from Python: load a scene, render it into NumPy arrays, write images.

    >>> import trazo
    >>> scene = trazo.load("scenes/cornell-box.toml")
    >>> image = trazo.render(scene, spp=64)          # H×W×3 float32, linear
    >>> trazo.write("box.png", image)

The same scene, seed and samples per pixel give the same image, bit for bit,
as ``trazo render`` on the command line. See docs/python.md.
"""

import math
import os
import sys

from . import _trazo
from ._trazo import Scene, TrazoError, read, write

__version__ = _trazo.__version__
__all__ = ["Scene", "TrazoError", "load", "render", "read", "write", "__version__"]


def load(source=None, **params):
    """A scene from a file (trazo TOML, Mitsuba 3 XML, pbrt-v4, glTF, OBJ, PLY),
    a dictionary in trazo's TOML layout, or the built-in Cornell box (no
    source). Keyword arguments are the scene's ``$name`` parameters (as
    ``trazo render -D name=value``)."""
    if source is None:
        if params:
            raise TrazoError("the built-in scene has no parameters: " + ", ".join(params))
        return _trazo.builtin()
    if isinstance(source, dict):
        if params:
            raise TrazoError("a dictionary scene has no parameters: " + ", ".join(params))
        return _trazo.load_toml(_to_toml(source), "<dict>")
    defines = [(name, _param(value)) for name, value in params.items()]
    return _trazo.load(os.fspath(source), defines)


def render(scene, *, spp=None, integrator=None, sampling=None, seed=None, threads=None,
           width=None, height=None, max_depth=None, aovs=(), progress=None):
    """Renders ``scene`` (from :func:`load`) and returns the image as an
    H×W×3 float32 array of linear radiance, scaled by the scene's exposure
    as ``trazo render`` scales its float images; with ``aovs`` (names among
    "albedo", "normal", "depth") a dict of the image ("color") and each
    auxiliary image (depth is H×W×1).

    The keywords override the scene's settings, as the command line's flags
    do. ``progress`` is True (a tqdm bar if tqdm is installed, else a line
    on stderr), or a function called with (samples per pixel done, total)
    after every pass. Ctrl-C stops the render within moments and raises
    KeyboardInterrupt."""
    if isinstance(scene, (str, os.PathLike, dict)):
        scene = load(scene)
    callback, close = _progress(progress)
    try:
        image, extra = _trazo.render(scene, spp, integrator, sampling, seed, threads, width, height,
                                     max_depth, list(aovs), callback)
    finally:
        close()
    if aovs:
        return {"color": image, **extra}
    return image


def _param(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _progress(progress):
    """A callback for the renderer and a function that closes what it opened."""
    if progress is None or progress is False:
        return None, lambda: None
    if callable(progress):
        return progress, lambda: None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        tqdm = None
    if tqdm is not None:
        bar = tqdm(total=None, unit="spp")

        def update(done, total):
            bar.total = total
            bar.n = done
            bar.refresh()

        return update, bar.close

    def line(done, total):
        sys.stderr.write(f"\rtrazo: {done}/{total} spp ({100 * done / total:.0f} %)")
        sys.stderr.flush()

    return line, lambda: sys.stderr.write("\n")


def _to_toml(scene):
    """A dictionary scene as TOML text: top-level values, then a table per
    dictionary, an array of tables per list of dictionaries."""
    lines, tables = [], []
    for key, value in scene.items():
        if isinstance(value, dict):
            tables.append([f"[{_key(key)}]"] + [f"{_key(k)} = {_value(v)}" for k, v in value.items()])
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for item in value:
                tables.append([f"[[{_key(key)}]]"] + [f"{_key(k)} = {_value(v)}" for k, v in item.items()])
        else:
            lines.append(f"{_key(key)} = {_value(value)}")
    for table in tables:
        lines.append("")
        lines.extend(table)
    return "\n".join(lines) + "\n"


def _key(key):
    key = str(key)
    if key and all(c.isalnum() or c in "-_" for c in key):
        return key
    return _string(key)


def _string(s):
    out = ['"']
    for c in s:
        if c in '"\\':
            out.append("\\" + c)
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(c)
    out.append('"')
    return "".join(out)


def _value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise TrazoError(f"a scene value must be a finite number, got {v}")
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, os.PathLike):
        return _string(os.fspath(v))
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if hasattr(v, "tolist"):  # NumPy arrays and scalars
        return _value(v.tolist())
    raise TrazoError(f"a scene value cannot be a {type(v).__name__}: {v!r}")
