"""The version of lbscene: a leaf module that every layer may import (it imports nothing)."""

__all__ = ["__version__"]

__version__ = "0.1.0"
