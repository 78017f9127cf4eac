"""Loading and writing the robots' MJCF files (`jaxloco/models/*.xml`, package data),
with one-line errors.

Each robot's `model.py` builds its MJCF from its parameters as an MjSpec and reads the
packaged file back with `load_spec` / `load_model`, to which scenarios add their
terrain. `python -m jaxloco.robots.<robot>.model` prints the generated MJCF and
`--write PATH` writes it where you say (in a checkout, `--write jaxloco/models/<file>`
regenerates the packaged file; a test checks that it is in sync).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco

from jaxloco import paths
from jaxloco.errors import SpecError

MODELS_DIR = Path(__file__).resolve().parents[1] / "models"  # the packaged MJCF files


def set_actuator_limits(act: mujoco.MjsActuator, ctrlrange: tuple[float, float], force: float) -> None:
    """Limit an MjSpec actuator's control to `ctrlrange` and its force to +-`force`
    (units of the actuator: N, N m, m/s, rad)."""
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.ctrlrange = list(ctrlrange)
    act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.forcerange = [-force, force]


def _first_line(exc: Exception) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def load_spec(path: str | Path) -> mujoco.MjSpec:
    """The MJCF file `path` as an MjSpec; SpecError (one line) if it is missing or broken."""
    path = Path(path)
    if not paths.is_file(path, where="model file"):
        raise SpecError(f"model file not found: {path}")
    try:
        return mujoco.MjSpec.from_file(str(path))
    except (ValueError, RuntimeError) as exc:  # mujoco: ValueError with a multi-line message
        raise SpecError(f"broken MJCF {path}: {_first_line(exc)}") from None


def load_model(path: str | Path) -> mujoco.MjModel:
    """`load_spec(path)` compiled; SpecError (one line) if it does not compile."""
    spec = load_spec(path)
    try:
        return spec.compile()
    except (ValueError, RuntimeError) as exc:
        raise SpecError(f"MJCF {path} does not compile: {_first_line(exc)}") from None


def xml_text(spec: mujoco.MjSpec) -> str:
    """The MJCF text of a spec (compiled first, as MjSpec.to_xml requires)."""
    spec.compile()
    return spec.to_xml()


def write_main(description: str, path: Path, text: Callable[[], str], argv: list[str] | None = None) -> None:
    """Command line of a robot's model module: print its generated MJCF, or write it to
    the path given with --write (one-line error and exit 2 if it cannot be written).
    `path` is the packaged file the text is meant to match."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--write", metavar="PATH", type=Path,
                        help=f"write the MJCF to PATH (the packaged copy is {path})")
    args = parser.parse_args(argv)
    out = text()
    if args.write is None:
        print(out)
        return
    try:
        args.write.write_text(out)
    except OSError as exc:
        parser.exit(2, f"error: cannot write {args.write}: {exc.strerror or exc}\n")
    print(f"wrote {args.write}")


@dataclass(frozen=True)
class ModelFile:
    """A robot's generated MJCF file: where it lives (`path`) and the MjSpec builder that
    writes it (`build`). A robot's model module exposes `load_spec`, `load_model`,
    `xml_text` and its `--write` command line from one of these."""

    path: Path
    build: Callable[[], mujoco.MjSpec]

    def load_spec(self, path: str | Path | None = None) -> mujoco.MjSpec:
        """The MJCF (default `self.path`) as an MjSpec; SpecError (one line) for a
        missing or broken file."""
        return load_spec(self.path if path is None else path)

    def load_model(self, path: str | Path | None = None) -> mujoco.MjModel:
        """`load_spec(path)` compiled; SpecError (one line) if it does not compile."""
        return load_model(self.path if path is None else path)

    def xml_text(self) -> str:
        """The MJCF text `build` generates."""
        return xml_text(self.build())

    def main(self, description: str, argv: list[str] | None = None) -> None:
        """The model module's command line: print the MJCF, or write it with --write PATH."""
        write_main(description, self.path, self.xml_text, argv)

