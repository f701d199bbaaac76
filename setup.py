"""Packaging beyond pyproject.toml: the top-level data folders go into the wheel inside the package.

``tasks/`` (stage YAMLs and recipes), ``assets/`` (MJCF) and ``policies/`` (shipped policies and
their manifest) sit at the top of the repository; the wheel carries them as ``mjnav/_data/<folder>``
(a package-dir mapping, which pyproject.toml's ``packages.find`` cannot express), where
:mod:`mjnav.resources` looks first. The sdist carries them through MANIFEST.in.
"""

from setuptools import find_packages, setup

#: Folder -> the files of it that ship.
DATA = {"tasks": ["*.yaml"], "tasks/recipes": ["*.yaml"], "assets": ["*.xml"], "policies": ["manifest.yaml", "*.pt"]}


def _package(folder: str) -> str:
    return "mjnav._data." + folder.replace("/", ".")


setup(
    packages=[*find_packages(include=["mjnav", "mjnav.*"]), *map(_package, DATA)],
    package_dir={_package(folder): folder for folder in DATA},
    package_data={_package(folder): patterns for folder, patterns in DATA.items()},
)
