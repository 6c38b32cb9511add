"""coastforge: one overhead image of a coastline in, a marine-robotics simulation environment out.

Kept free of heavy imports so that ``coastforge --help`` answers instantly.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
