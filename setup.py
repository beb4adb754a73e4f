"""Build configuration that pyproject.toml cannot express: the shipped models stay in ``models/`` in the
repository and are packaged as ``aamtrack/_models/*.npz`` (package data, read with importlib.resources), so they
are found wherever pip puts the package: venvs, ``--user``, ``--target``, editable installs."""

from setuptools import find_packages, setup

setup(
    packages=find_packages(include=["aamtrack*"]) + ["aamtrack._models"],
    package_dir={"aamtrack._models": "models"},
    package_data={"aamtrack": ["py.typed"], "aamtrack._models": ["*.npz"]},
)
