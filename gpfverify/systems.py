"""Load a user's system from ``SYSTEM.py:NAME`` (the ``gpfverify check`` argument).

``SYSTEM.py`` is imported as a module of its own, with its folder first on ``sys.path`` while it
loads and while ``NAME()`` builds the model (so helper modules next to it import; ``sys.path`` is
restored afterwards); ``NAME`` must be a
:class:`~gpfverify.models.StateSpaceModel`, Stone Soup models or filterpy filters
(:func:`gpfverify.adapters.as_state_space_model`), or a function of no arguments returning one. Every
failure — no such file, the file raising while it is imported, no such name, not a model, a model
function that raises or returns the wrong shape when the model is built — is an
:class:`~gpfverify.errors.InputError` whose message names the file and the cause in one line.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

from gpfverify.adapters import as_local_filters
from gpfverify.adapters.local_filters import LocalFilters
from gpfverify.errors import GpfverifyError, InputError
from gpfverify.models import StateSpaceModel


def split_spec(spec: str) -> tuple[Path, str]:
    """``"path/to/system.py:NAME"`` → (absolute path, NAME)."""
    path, sep, name = str(spec).rpartition(":")
    if not sep or not path or not name.isidentifier():
        raise InputError(f"the system must be given as SYSTEM.py:NAME, got {spec!r}")
    return Path(path).expanduser().resolve(), name


@contextmanager
def _folder_on_path(folder: Path):
    """``folder`` first on ``sys.path`` for the duration, ``sys.path`` as it was afterwards."""
    saved = list(sys.path)
    sys.path.insert(0, str(folder))
    try:
        yield
    finally:
        sys.path[:] = saved


def load_system(spec: str) -> StateSpaceModel:
    """The model ``NAME`` defined in ``SYSTEM.py`` (module docstring)."""
    return load_filters(spec).model


def load_filters(spec: str) -> LocalFilters:
    """The model ``NAME`` defined in ``SYSTEM.py`` with what its library's filters carry
    (:func:`gpfverify.adapters.as_local_filters`: family, sigma points, each filter's start)."""
    path, name = split_spec(spec)
    module = _load_module(path)
    if not hasattr(module, name):
        raise InputError(f"{path.name} defines no {name!r}")
    return as_filters(getattr(module, name), path, name)


def _load_module(path: Path) -> ModuleType:
    """``SYSTEM.py`` imported once per process (later calls get the same module)."""
    if not path.is_file():
        raise InputError(f"no such file: {path}")
    module_name = "gpfverify_user_system_" + hashlib.sha1(str(path).encode()).hexdigest()[:12]
    module = sys.modules.get(module_name)
    if module is not None:
        return module
    module_spec = importlib.util.spec_from_file_location(module_name, path)
    if module_spec is None or module_spec.loader is None:
        raise InputError(f"{path} is not a Python file")
    module = importlib.util.module_from_spec(module_spec)
    try:
        with _folder_on_path(path.parent):
            module_spec.loader.exec_module(module)
    except GpfverifyError as exc:
        raise InputError(f"{path.name}: {exc}") from exc
    except Exception as exc:  # the user's code
        raise InputError(f"{path.name} raised {type(exc).__name__} while loading: {exc}") from exc
    sys.modules[module_name] = module
    return module


def as_filters(obj: object, path: Path, name: str) -> LocalFilters:
    """The object ``NAME`` of ``SYSTEM.py`` as a :class:`~gpfverify.models.StateSpaceModel` with its
    library's filters: a model as it is, a function of no arguments called (with the system's
    folder on ``sys.path``) and its result taken the same way. The one place where what the
    system file defines is turned into a model."""
    model = obj
    if callable(model) and not isinstance(model, StateSpaceModel):
        try:
            with _folder_on_path(path.parent):
                model = model()
        except GpfverifyError as exc:
            raise InputError(f"{path.name}:{name}(): {exc}") from exc
        except Exception as exc:
            raise InputError(f"{path.name}:{name}() raised {type(exc).__name__}: {exc}") from exc
    return as_local_filters(model, f"{path.name}:{name}")
