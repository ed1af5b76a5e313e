"""osmap's build backend: setuptools', plus a portable kernel cache in every wheel.

A wheel build (``pip install .``, ``pip wheel .``, ``python -m build``) installs the runtime
dependencies into the build environment as well, and after setuptools has laid out the package
runs ``python -m osmap_cli.kernelwarm portable`` on it: every kernel compiled for the generic
CPU of the architecture into ``osmap_kernels/portable-cache/`` (about 40 s on two cores), so
that the first run after the install does not compile (osmap_cli/kernelwarm.py says how it is
used). The wheel is then tagged for this Python and platform, as its cache files are.

Editable installs (``pip install -e .``, ``make venv``) skip it: a development tree compiles on
first use (``make demo`` builds the cache for its tree). If the step fails, the wheel is built
without it and says so; osmap then compiles on first use, as it would anyway.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile

from setuptools import build_meta as _setuptools
from setuptools.build_meta import *  # noqa: F401,F403 - the backend's other hooks
from setuptools.command.build_py import build_py as _build_py

try:
    from setuptools.command.bdist_wheel import bdist_wheel as _bdist_wheel
except ImportError:  # setuptools < 70.1
    from wheel.bdist_wheel import bdist_wheel as _bdist_wheel


def _runtime_requirements() -> list[str]:
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    with open("pyproject.toml", "rb") as handle:
        return list(tomllib.load(handle)["project"]["dependencies"])


def get_requires_for_build_wheel(config_settings=None):
    """setuptools' build requirements, and the runtime ones the kernel compile imports."""
    return (_setuptools.get_requires_for_build_wheel(config_settings)
            + _runtime_requirements())


class BuildPy(_build_py):
    """build_py, then the portable kernel cache into the built package."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        dest = os.path.join(os.path.abspath(self.build_lib), "osmap_kernels", "portable-cache")
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            p for p in (os.path.abspath(self.build_lib), env.get("PYTHONPATH")) if p)
        with tempfile.TemporaryDirectory(prefix="osmap-build-") as scratch:
            done = subprocess.run([sys.executable, "-m", "osmap_cli.kernelwarm", "portable",
                                   dest], env=env, cwd=scratch)
        if done.returncode != 0:
            shutil.rmtree(dest, ignore_errors=True)
            print("osmap: warning: the portable kernel cache could not be built; the first run "
                  "will compile the kernels", file=sys.stderr)


class BdistWheel(_bdist_wheel):
    """A wheel for this Python and platform: the cache's files are."""

    def finalize_options(self):
        super().finalize_options()
        self.root_is_pure = False
