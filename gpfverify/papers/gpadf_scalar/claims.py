"""Every claim of Deisenroth et al. 2009 (ICML, ref. [7] of Liao et al. 2019) the scalar benchmark
judges: its Table 1 (NLL, Mahalanobis distance and RMSE of UKF, EKF, GP-UKF and GP-ADF on the
one-step example of its §5) and its reading of that table — GP-ADF the only consistent filter, the
others over-confident. The paper's text is not held here, so each claim is located by its table.
"""

from __future__ import annotations

from gpfverify.contract.claims import Statement

TABLE_1 = Statement("claim", "Deisenroth et al. 2009, §5, Table 1 (ref. [7] of Liao et al. 2019)")
