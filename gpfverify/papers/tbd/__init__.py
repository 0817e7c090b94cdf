"""Chen, Liang, Pan, Liang, *PF track-before-detect with two-stage measurement update*, Chinese Journal of
Sensors and Actuators 28(1) 2015 (seed 004): PF-TBD against TPFTBD (``tbd``). The filters themselves are
the shared engine :mod:`gpfverify.filters.tbd`."""
