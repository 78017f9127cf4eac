"""Choosing MuJoCo's OpenGL backend (MUJOCO_GL) for offscreen rendering.

MuJoCo picks its OpenGL backend from the environment variable MUJOCO_GL when `mujoco`
is imported: "egl" (headless, GPU driver's EGL; also Mesa's software EGL), "osmesa"
(headless, pure CPU, slower), "glfw" (a desktop with a display; the default). On Linux
without a display ($DISPLAY and $WAYLAND_DISPLAY unset) and MUJOCO_GL unset,
`choose_backend` tries "egl" and then "osmesa" in a short subprocess (a failed OpenGL
initialisation cannot be undone in this process), sets MUJOCO_GL to the first that
creates a context and says so when it had to fall back. A MUJOCO_GL set by the user is
kept. `make_renderer` then binds that backend even if `mujoco` was imported before the
variable was set, and turns a failed context into one `SpecError` line.
"""

from __future__ import annotations

import ctypes.util
import importlib
import os
import subprocess
import sys
import warnings

from jaxloco.errors import SpecError

HEADLESS = ("egl", "osmesa")
KNOWN = ("egl", "osmesa", "glfw", "glx", "cgl", "wgl", "enable", "enabled", "on", "true", "1")
HINT = "use MUJOCO_GL=egl (GPU or headless server) or MUJOCO_GL=osmesa (CPU only); glfw needs a display"
OSMESA_INSTALL = ("apt install libosmesa6 (Debian/Ubuntu), dnf install mesa-libOSMesa (Fedora) "
                  "or conda install -c conda-forge mesalib")
_PROBE = "import mujoco; c = mujoco.GLContext(16, 16); c.make_current(); c.free()"
_probed: dict[str, tuple[bool, str]] = {}
notes: list[str] = []  # what choose_backend decided, for the command to print


def has_osmesa() -> bool:
    """Whether the OSMesa library (libOSMesa), which MUJOCO_GL=osmesa loads, can be found."""
    return ctypes.util.find_library("OSMesa") is not None


def hint(backend: str, osmesa_found: bool | None = None) -> str:
    """What to do after MUJOCO_GL=backend failed (one line). For osmesa: name libOSMesa,
    whether it was found (`osmesa_found`, looked up when None) and how to install it, and
    suggest egl instead; for the other backends the general HINT."""
    if backend != "osmesa":
        return HINT
    if osmesa_found is None:
        osmesa_found = has_osmesa()
    state = "was found but does not work" if osmesa_found else "was not found"
    return (f"libOSMesa (the OSMesa library that MUJOCO_GL=osmesa loads) {state}: install it with "
            f"{OSMESA_INSTALL}; or use MUJOCO_GL=egl (GPU or headless server)")


def is_linux() -> bool:
    return sys.platform.startswith("linux")


def has_display() -> bool:
    """Whether a window can be opened: on Linux $DISPLAY or $WAYLAND_DISPLAY is set."""
    if not is_linux():
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def probe(backend: str, timeout: float = 60.0) -> tuple[bool, str]:
    """(works, why not) for MUJOCO_GL=backend, tried in a subprocess (cached)."""
    if backend not in _probed:
        env = dict(os.environ, MUJOCO_GL=backend)
        env.pop("PYOPENGL_PLATFORM", None)
        try:
            with warnings.catch_warnings():  # JAX warns about any fork; this is fork + exec
                warnings.filterwarnings("ignore", message="os.fork", category=RuntimeWarning)
                done = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True,
                                      text=True, timeout=timeout, check=False)
            lines = [line for line in done.stderr.strip().splitlines() if line.strip()]
            _probed[backend] = (done.returncode == 0, lines[-1] if lines else f"exit code {done.returncode}")
        except (OSError, subprocess.TimeoutExpired) as exc:
            _probed[backend] = (False, f"{type(exc).__name__}: {exc}")
    return _probed[backend]


def choose_backend() -> str:
    """The MUJOCO_GL backend for offscreen rendering ("" = MuJoCo's default, glfw). Sets
    MUJOCO_GL when it is unset on a Linux machine without a display (see the module
    docstring); SpecError when neither EGL nor OSMesa works there."""
    current = os.environ.get("MUJOCO_GL", "").strip().lower()
    if current and current not in KNOWN:
        raise SpecError(f"MUJOCO_GL={current} is not an OpenGL backend; {HINT}")
    if current or not is_linux() or has_display():
        return current
    ok, why_egl = probe("egl")
    if ok:
        os.environ["MUJOCO_GL"] = "egl"
        return "egl"
    ok, why_osmesa = probe("osmesa")
    if ok:
        os.environ["MUJOCO_GL"] = "osmesa"
        notes.append(f"EGL failed ({why_egl}); rendering on the CPU with MUJOCO_GL=osmesa (slower)")
        return "osmesa"
    raise SpecError(f"no display and no headless OpenGL: MUJOCO_GL=egl failed ({why_egl}) and MUJOCO_GL=osmesa "
                    f"failed ({why_osmesa}); install an EGL driver or libOSMesa ({OSMESA_INSTALL})")


def _bind(backend: str) -> None:
    """Make mujoco.Renderer use `backend` (egl, osmesa, glfw) even if mujoco chose another
    one at import."""
    if backend not in (*HEADLESS, "glfw"):
        return
    from mujoco.rendering.classic import gl_context

    current = getattr(gl_context, "GLContext", None)
    if current is not None and getattr(current, "__module__", "").startswith(f"mujoco.{backend}"):
        return
    try:
        module = importlib.import_module(f"mujoco.{backend}")
    except Exception as exc:  # noqa: BLE001 - any failure of the backend is the user's setup
        raise SpecError(f"MUJOCO_GL={backend} cannot be used: {type(exc).__name__}: {_first(exc)}; "
                        f"{hint(backend)}") from None
    gl_context.GLContext = module.GLContext


def _first(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def check_context() -> str:
    """Choose the backend and create (and free) a tiny renderer with it: one SpecError
    line now, rather than after a long replay, when OpenGL does not work."""
    backend = choose_backend()
    try:  # MuJoCo binds MUJOCO_GL's backend when imported: a broken one fails right here
        import mujoco
    except Exception as exc:  # noqa: BLE001 - e.g. AttributeError from PyOpenGL without libOSMesa
        raise SpecError(f"MUJOCO_GL={backend}: importing mujoco failed ({type(exc).__name__}: {_first(exc)}); "
                        f"{hint(backend)}") from None
    make_renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 16, 16).close()
    return backend


def make_renderer(model, height: int, width: int):
    """A `mujoco.Renderer` (offscreen framebuffer enlarged to fit) or one SpecError line."""
    backend = choose_backend()
    _bind(backend)
    import mujoco

    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), int(width))
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), int(height))
    try:
        with warnings.catch_warnings():  # glfw warns (then fails) without a display
            warnings.simplefilter("ignore")
            return mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # noqa: BLE001 - GL failures come as many exception types
        name = backend or "glfw (default)"
        raise SpecError(f"cannot create an OpenGL context with MUJOCO_GL={name}: {type(exc).__name__}: "
                        f"{_first(exc)}; {hint(backend)}") from None
