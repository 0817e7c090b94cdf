"""gpfverify: Gaussian-process filters and multisensor estimation fusion, implemented, written
symbolically, verified and benchmarked."""

__version__ = "0.1.0"
