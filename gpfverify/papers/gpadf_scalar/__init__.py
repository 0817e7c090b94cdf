"""Deisenroth, Huber, Hanebeck, *Analytic Moment-based Gaussian Process Filtering*, ICML 2009 (reference
[7] of the fusion paper): the scalar benchmark (``gpadf-scalar``) of UKF, EKF, GP-UKF and GP-ADF."""
