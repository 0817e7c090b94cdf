"""Zhou, Liu, Su, *Particle flow filter based on “innovation error”*, Journal of Computer Applications
2020(11) (seed 003): the UNGM and gamma-noise experiment (``pff1d_*``) and bearing-only tracking
(``bearing_*``), with the filters they run (``methods``), their shared contract and one report section."""
