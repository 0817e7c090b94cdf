"""Every claim of Liao et al. 2019 (seed 000) the fusion experiments judge: where the paper makes
it, in its words (:class:`~gpfverify.contract.claims.Statement`), and the comparisons the toolkit
adds, which the paper does not make (diagnostics).

The quotes are the paper's sentences as printed; letters the text extraction dropped are restored
in square brackets ("ran[k]"). A comparison is the paper's claim only where the paper states it: the
1-D example (§4.1, Figs. 2–4) compares the sensors with fusion and GP-ADF with GP-UKF, never with
RCC-CI or CW, and shows Sensor 1 and Sensor 2 apart only at σ² = 1 and 2 (Figs. 2, 3; Fig. 4 shows
"Single-GP-ADF" and "Single-GP-UKF"); the constant-turn example states its comparisons with the
sensors and the baselines, and on computation time, for κ = 300 (Figs. 6–9); for κ = 30 and 60 its
Figs. 12–15 show CMF and DMF alone, and its text compares only GP-UKF with GP-ADF there.
"""

from __future__ import annotations

from gpfverify.contract.claims import Statement
from gpfverify.papers.fusion.ct2d_contract import LARGE_TRAINING
from gpfverify.papers.fusion.moments_contract import SOURCE_EQUATIONS
from gpfverify.papers.fusion.ungm1d_contract import FIGURE_NOISES

PROPOSITION_1 = Statement(
    "claim", "§3, Proposition 1 (eq. 35)",
    "Assume that all cross terms C_xy^m, m = 1,..., N are full column ran[k], the distributed estimation fusion is "
    "equivalent to the centralized estimation fusion as follows")

# ---- §4.1, the 1-D example ------------------------------------------------------------------------

UNGM_SENSOR_2 = Statement(
    "claim", "§4.1, Figs. 2 and 3",
    "According to the average Mahalanobis distances in Figures 2 and 3, we can see that the estimation performance "
    "of Sensor 2 is better than that of Sensor 1.")
UNGM_FUSION_BEATS_SENSORS = Statement(
    "claim", "§4.1, Figs. 2 and 3",
    "Furthermore, the multisensor estimation fusion methods perform better than the single sensor filters with "
    "GP-ADF and GP-UKF, respectively.")
UNGM_FIGURE_4 = Statement(
    "claim", "§4.1, Fig. 4",
    "From Figure 4, we can see that the proposed fusion methods enjoy better performance for different system "
    "noises.")
UNGM_FAMILIES = Statement(
    "claim", "§4.1, Figs. 2 and 3",
    "In addition, GP-ADF fusion performs better than GP-UKF fusion for the system noise σ² = 1 and GP-UKF fusion "
    "performs better than GP-ADF fusion for the system noise σ² = 2.")
UNGM_BASELINES = Statement(
    "diagnostic", "§4.1 compares fusion with the single sensors only (Figs. 2–4 show no RCC-CI or CW); the "
                  "comparison with the baselines is §4.2's, applied here to the 1-D example")
UNGM_SENSOR_2_FIG_4 = Statement(
    "diagnostic", "Fig. 4 shows one single-sensor curve per family, not Sensor 1 and Sensor 2 apart; §4.1 compares "
                  "the sensors at σ² = 1 and 2 only")

def ungm1d_statement(name: str, noise: float | None) -> Statement:
    """The statement of a 1-D claim (``name``: the id's claim part) at σ² = ``noise`` (None: a claim
    over every σ²)."""
    in_figures = noise in FIGURE_NOISES
    if name == "dmf-equals-cmf":
        return PROPOSITION_1
    if name == "fusion-beats-sensors":
        return UNGM_FUSION_BEATS_SENSORS if in_figures else UNGM_FIGURE_4
    if name == "fusion-beats-sensors-every-noise":
        return UNGM_FIGURE_4
    if name == "fusion-beats-baselines":
        return UNGM_BASELINES
    if name == "sensor2-beats-sensor1":
        return UNGM_SENSOR_2 if in_figures else UNGM_SENSOR_2_FIG_4
    if name.startswith("fusion-gp-"):
        return UNGM_FAMILIES
    raise KeyError(f"ungm1d claim {name!r} has no statement")


# ---- §4.2, the constant turn ----------------------------------------------------------------------

CT_FULL_RANK_300 = Statement(
    "claim", "§4.2, case 1, Fig. 5",
    "From Figure 5, we can see that the ratios of full ran[k] are all equal to 100%.")
CT_EQUAL = Statement(
    "claim", "§4.2, case 1, Figs. 6 and 7; Proposition 1",
    "Meanwhile, from Figures 6 and 7, the RMSE of the distributed estimation fusion is the same as that of the "
    "centralized estimation fusion based on GP-ADF and GP-UKF, respectively.")
CT_BROKEN = Statement(
    "claim", "§4.2, case 2, Figs. 12 and 13",
    "Thus, the equivalence between the centralized and distributed estimation fusion with GP-UKF is broken in "
    "Figures 12 and 13, respectively.")
CT_SENSORS = Statement(
    "claim", "§4.2, case 1, Figs. 6 and 7",
    "From Figures 6 and 7, it can be seen that the RMSE of the multisensor estimation fusion method is lower than "
    "that of the single sensor filtering.")
CT_BASELINES = Statement(
    "claim", "§4.2, case 1, Figs. 6 and 7",
    "In addition, the RMSE of multisensor estimation fusion method is lower than that of the RCC-CI algorithm and "
    "the convex combination method.")
CT_LOSES_RANK = Statement(
    "claim", "§4.2, case 2, Figs. 10 and 11",
    "From Figures 10 and 11, it can be seen that the ratios of full ran[k] are both less than 100% for the single "
    "sensor GP-UKF case with κ = 30 and κ = 60 training data.")
CT_FAMILIES = Statement(
    "claim", "§4.2, case 2, Figs. 6, 12 and 13",
    "We can also see that the performance of GP-UKF fusion is better than that of GP-ADF fusion with κ = 300 "
    "training data from Figure 6 and a little worse with κ = 30, 60 training data from Figures 12 and 13.")
CT_DMF_TIME = Statement(
    "claim", "§4.2, case 1, Figs. 8 and 9",
    "From Figures 8 and 9, we can find that the computation time of the distributed estimation fusion is less than "
    "that of the centralized estimation fusion.")
CT_RCC_TIME = Statement(
    "claim", "§4.2, case 1, Figs. 8 and 9",
    "The computation time of the proposed fusion methods is much less than that of the RCC-CI algorithm.")
CT_CW_TIME = Statement(
    "claim", "§4.2, case 1, Figs. 8 and 9",
    "The convex combination method ta[k]es the least computation time, since it directly uses the weight "
    "combination with covariance.")
CT_FAMILY_TIME = Statement(
    "claim", "§4.2, case 2, Figs. 8, 14 and 15",
    "Meanwhile, from Figures 8, 14 and 15, the average computation time of GP-UKF fusion is less than that of "
    "GP-ADF fusion with κ = 300 training data and is contrary with κ = 30, 60 training data.")
CT_UPDATE_TIME = Statement(
    "diagnostic", "a reading of “computation time” (§4.2) the paper does not state: the update alone, once the "
                  "measurements arrive, against the whole fusion step it may have timed")
CT_SMALL_TRAINING = Statement(
    "diagnostic", "for κ = 30 and 60 the paper shows CMF and DMF alone (Figs. 12–15: no single sensor, no RCC-CI or "
                  "CW curve) and compares only GP-UKF with GP-ADF there; this comparison is §4.2 case 1's, applied "
                  "to the smaller training sets")
CT_OTHER_TURN = Statement(
    "diagnostic", "the paper compares GP-UKF with GP-ADF fusion at κ = 300 on Fig. 6 (Ω = 2π/90) only; this is the "
                  "same comparison at Ω = 0.5 (Fig. 7)")

def ct2d_statement(name: str, kappa: int, omega_is_small_turn: bool) -> Statement:
    """The statement of a constant-turn claim (``name``: the id's claim part) at κ = ``kappa``, on the
    small turn Ω = 2π/90 (``omega_is_small_turn``) or another."""
    large = kappa >= LARGE_TRAINING
    if name == "dmf-equals-cmf":
        return CT_EQUAL if large else PROPOSITION_1
    if name == "gp-ukf-equivalence-broken":
        return CT_BROKEN
    if name == "full-rank-every-step":
        return CT_FULL_RANK_300
    if name == "gp-ukf-loses-full-rank":
        return CT_LOSES_RANK
    if name in ("fusion-beats-sensors", "fusion-beats-baselines", "dmf-cheaper-than-cmf", "rcc-ci-costs-most",
                "cw-fastest"):
        if not large:
            return CT_SMALL_TRAINING
        return {"fusion-beats-sensors": CT_SENSORS, "fusion-beats-baselines": CT_BASELINES,
                "dmf-cheaper-than-cmf": CT_DMF_TIME, "rcc-ci-costs-most": CT_RCC_TIME,
                "cw-fastest": CT_CW_TIME}[name]
    if name == "dmf-update-cheaper-than-cmf":
        return CT_UPDATE_TIME
    if name in ("gp-ukf-fusion-vs-gp-adf", "gp-ukf-fusion-time-vs-gp-adf"):
        if large and not omega_is_small_turn:
            return CT_OTHER_TURN
        return CT_FAMILIES if name == "gp-ukf-fusion-vs-gp-adf" else CT_FAMILY_TIME
    raise KeyError(f"ct2d claim {name!r} has no statement")


# ---- §2.3: the moments GP-ADF rests on ------------------------------------------------------------

CLOSED_FORM_CHECKS = Statement(
    "diagnostic", f"{SOURCE_EQUATIONS} (§2.3): the toolkit's check of its closed-form moments (which the paper "
                  "takes from Deisenroth et al. 2009) against Gauss–Hermite quadrature and Monte Carlo: the paper "
                  "states the closed form, it claims no numbers about it")


def claim_name(claim_id: str) -> str:
    """The claim part of an id: "ungm1d/s1.0/fusion-beats-sensors/GP-ADF" -> "fusion-beats-sensors"
    (the experiment, the σ² slug and the family are not part of it)."""
    parts = claim_id.split("/")[1:]
    parts = [p for p in parts if not (p.startswith("s") and p[1:].replace(".", "").isdigit())]
    return parts[0]
