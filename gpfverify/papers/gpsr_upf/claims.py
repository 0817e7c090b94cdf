"""Every claim of Meng et al. 2015 (seed 001) the sins-gps experiment judges, where the paper makes
it, in its words (:class:`~gpfverify.contract.claims.Statement`), and the supplementary checks the
toolkit adds (diagnostics: the paper makes no claim about the proposal filters alone or about its
scenario's room for improvement).

The quotes are the paper's sentences as printed; the pronunciation glosses the text extraction
inserted after characters are left out. The attitude paragraph of §3 writes "位置誤差" (position)
and "速度誤差" (velocity) where its figures (5 and 6) and the sentence's units (′) are about
attitude: those claims are read as the attitude's.
"""

from __future__ import annotations

from gpfverify.contract.claims import Statement

_POSITION = ("可以看出,在勻速飛行時段,采用UPF算法得到的東向、北向以及天向的位置誤差穩定在(-7.5 m,+7.9 m);"
             "而采用GPSR-UPF算法得到的東向、北向以及天向的位置誤差穩定在(-4.9 m,+4.9 m)。")
_VELOCITY = ("在勻速飛行時段,通過UPF算法計算得到的速度誤差范圍穩定在(-1.8 m/s,+1.5 m/s);"
             "而由GPSR-UPF算法計算得到的速度誤差范圍穩定在(-1.0 m/s,+1.2 m/s)。")
_ATTITUDE = ("在勻速飛行時段,通過UPF算法計算得到的姿態誤差范圍穩定在(-1.4′,+1.6′)內;"
             "采用GPSR-UPF算法計算得到的姿態誤差范圍穩定在(-0.9′,+1.0′)以內。")
_POSITION_MANOEUVRES = ("0~200 s時間段,GPSR-UPF算法相對于UPF算法,其位置誤差估計受系統變化的影響要小于UPF算法;"
                        "而在500~600 s時間段,GPSR的位置誤差估計穩定在±10 m以內,而UPF算法的位置誤差明顯高于前者。")
_VELOCITY_MANOEUVRES = ("0~200 s時間段,GPSR-UPF算法相對于UPF算法在速度誤差估計上差別不大;在500~600 s時間段,"
                        "GPSR的速度誤差估計穩定在(-1.5 m/s,+2.0 m/s)以內,而UPF算法的速度誤差最高達到了3.3 m/s。")
_ATTITUDE_MANOEUVRES = ("在0~200 s時間段GPSR-UPF算法的位置誤差明顯小于UPF算法;在500~600 s時間段,"
                        "GPSR的速度誤差估計穩定在(-1.9′,+1.6′)以內,而UPF算法的速度誤差接近±3′,具體結果如表1所示。")
_TABLE_1 = "新算法對于位置和速度的解算誤差相比基本UPF算法能夠降低約33%左右,其對于姿態的跟蹤誤差能夠降低約40%。"

REDUCTION = Statement("claim", "§3, Table 1", _TABLE_1)
FACTORS_VALID = Statement("claim", "§0 (introduction)",
                          "同時,采用平方根變換,利用協方差平方根代替協方差參加遞推運算來保證系統狀態協方差陣的正定性。")
CRUISE = {"position": Statement("claim", "§3, Figs. 1 and 2", _POSITION),
          "velocity": Statement("claim", "§3, Figs. 3 and 4", _VELOCITY),
          "attitude": Statement("claim", "§3, Figs. 5 and 6", _ATTITUDE)}
MANOEUVRES = {"position": Statement("claim", "§3, Figs. 1 and 2", _POSITION_MANOEUVRES),
              "velocity": Statement("claim", "§3, Figs. 3 and 4", _VELOCITY_MANOEUVRES),
              "attitude": Statement("claim", "§3, Figs. 5 and 6", _ATTITUDE_MANOEUVRES)}
SINGLE_FILTER = Statement(
    "diagnostic", "the toolkit's check beside §3, Table 1: its reductions applied to the proposal filters alone "
                  "(SR-UKF → GP-SR-UKF), which the paper does not run")
CEILING = Statement(
    "diagnostic", "the toolkit's check beside §3, Table 1: whether this scenario's model error leaves room for the "
                  "claimed reductions at all (an SR-UKF that knows the true model), which the paper does not ask")


def statement_of(slug: str) -> Statement:
    """The statement of a claim by the part of its id after "sins-gps/"."""
    if slug == "factors-valid":
        return FACTORS_VALID
    kind, _, quantity = slug.rpartition("-")
    if kind in ("cruise-band", "manoeuvre-0-200", "manoeuvre-500-600"):
        return (CRUISE if kind == "cruise-band" else MANOEUVRES)[quantity]
    return {"reduction": REDUCTION, "single-filter-reduction": SINGLE_FILTER, "true-model-ceiling": CEILING}[kind]
