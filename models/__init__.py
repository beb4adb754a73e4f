"""The shipped default models (``3d.npz``, ``2d.npz``). This folder is packaged as ``aamtrack._models`` (see
setup.py) so that ``aamtrack.models`` finds the files with importlib.resources wherever pip installs them."""
