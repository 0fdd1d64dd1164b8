"""thrombojax: fast learned surrogates of mechanical-thrombectomy simulations."""

__version__ = "0.1.0"

__all__ = ["__version__"]
