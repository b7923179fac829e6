"""parsph: SPH for the solid phase of granular two-fluid models."""
__version__ = "0.1.0"
