"""crlbswarm: CRLB-optimal UAV formations for cooperative range sensing.

Implements and extends Wu, Jin, Su, Li, Pan, Chan, "Formation Control for CRLB-Optimal
Cooperative Sensing in Low-Altitude Wireless Networks", arXiv:2602.23990 (2026).

Positions are horizontal coordinates in metres, shape ``(..., M, 2)`` (UAVs are rows);
every function accepts any leading batch shape. Angles are radians inside the library.

The public names (listed, with their modules, in ``__init__.pyi``) are imported on first
use, so ``import crlbswarm`` is instant and loads none of the heavy libraries (Numba, SciPy,
Matplotlib, Dask) until something that needs them is used.
"""

import lazy_loader

__version__ = "0.1.0"

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
