"""Build step: ship the top-level ``fmu_templates/`` inside the package.

Everything else about the package is in ``pyproject.toml``. ``fmu_templates/`` is the one
source of the C FMU templates; a wheel carries a copy at ``gatetwin/fmu/templates`` so that
``gatetwin export --backend c`` works from a non-editable install.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

TEMPLATES = Path(__file__).resolve().parent / "fmu_templates"
SHIPPED = ("*.c", "*.h", "*.txt", "*.md")


class BuildPyWithTemplates(build_py):
    """``build_py`` that also copies the FMU templates into the built package."""

    def run(self) -> None:
        super().run()
        target = Path(self.build_lib) / "gatetwin" / "fmu" / "templates"
        target.mkdir(parents=True, exist_ok=True)
        for pattern in SHIPPED:
            for src in sorted(TEMPLATES.glob(pattern)):
                shutil.copy2(src, target / src.name)


setup(cmdclass={"build_py": BuildPyWithTemplates})
