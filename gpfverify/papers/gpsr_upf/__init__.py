"""Meng, Gao, Wang, *Square-root UPF based on Gaussian process regression*, Systems Engineering and
Electronics 37(12) 2015 (seed 001): the SINS/GPS experiment (``sins-gps``) comparing UPF and GPSR-UPF."""
