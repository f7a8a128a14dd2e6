"""The example input files shipped with qsma: TOML configurations and the mesh files
they read, installed with the package (package data) and found through
:mod:`importlib.resources`, so that they are there in a wheel or an sdist as in a
clone of the repository."""
from __future__ import annotations

from importlib.resources import files
from pathlib import Path
import shutil

from ..errors import InputError

#: Folder of the example files inside the package.
DATA = "data"


def example_dir() -> Path:
    """The installed folder holding the example files."""
    return Path(str(files("qsma.examples").joinpath(DATA)))


def example_files() -> list[str]:
    """Names of the example files (configurations and meshes), sorted."""
    return sorted(p.name for p in example_dir().iterdir() if p.is_file()
                  and not p.name.startswith((".", "_")))


def example_file(name) -> Path:
    """The path of the example file ``name`` (e.g. ``"sandwich-2d.toml"``).

    Raises
    ------
    InputError
        no such example file, with the names there are.
    """
    if name not in example_files():
        raise InputError(f"no example file {name!r}; the examples are {example_files()}")
    return example_dir() / name


def copy_examples(dest) -> list[Path]:
    """Copy every example file into the folder ``dest`` (created if needed), to run
    and edit them there; returns the paths written.

    Raises
    ------
    InputError
        a file of that name exists in ``dest`` already (nothing is overwritten).
    """
    dest = Path(dest)
    taken = [n for n in example_files() if (dest / n).exists()]
    if taken:
        raise InputError(f"{str(dest / taken[0])!r} exists; copy the examples into an "
                         f"empty or new folder (nothing is overwritten)")
    dest.mkdir(parents=True, exist_ok=True)
    return [Path(shutil.copy2(example_file(n), dest / n)) for n in example_files()]


__all__ = ["example_dir", "example_files", "example_file", "copy_examples"]
