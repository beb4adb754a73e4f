"""aamtrack: real-time face tracking with Active Appearance Models (2D and 3D) and facial motion transfer."""

__version__ = "0.1.0"
