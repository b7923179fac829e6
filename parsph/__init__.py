"""parsph: SPH for the solid phase of granular two-fluid models."""
__version__ = "0.1.0"

from .blas_threads import apply as _blas_threads

_blas_threads()  # before numpy loads OpenBLAS

from .compile_settings import apply as _compile_settings  # noqa: E402
from .numba_cache import keep_in_step as _keep_in_step  # noqa: E402

_compile_settings()  # before any loop compiles

try:
    _keep_in_step()  # numba's cached loops were built from these sources, or go
except Exception:  # noqa: BLE001 - a cache that cannot be checked is only slower or stale, as numba leaves it
    pass
