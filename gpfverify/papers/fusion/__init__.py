"""Liao, Xie, Wang, Shen, *Multisensor Estimation Fusion with Gaussian Process for Nonlinear Dynamic
Systems*, Entropy 21 (2019) 1126 (seed 000): GP moment matching (``moments_*``), the 1-D two-sensor
example (``ungm1d_*``) and the 2-D constant turn (``ct2d_*``), with the scenario, contract, run and
report section the two fusion experiments share and the reference-page script (``page.py``)."""
