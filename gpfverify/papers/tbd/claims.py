"""Every claim of Chen et al. 2015 (seed 004) the tbd experiment judges, where the paper makes it,
in its words (:class:`~gpfverify.contract.claims.Statement`).

The quotes are the paper's sentences as printed (traditional characters, its own ("高于")); the
pronunciation glosses the text extraction inserted after characters (("級(jí)")) are left out.
Section 3.1 (6 dB, Figs. 1–3) claims better detection *and* estimation for TPFTBD, and that
TPFTBD with N = 1000 still performs better than PF-TBD with N = 2000; §3.2 (Fig. 4, Table 1) the SNR
gains, where they shrink, and the running times; §3.3 (Figs. 5, 6) the transfer parameter ζ.
"""

from __future__ import annotations

from gpfverify.contract.claims import Statement

_FIGS_1_3 = ("由圖1~圖3可以看出,改進算法較原算法獲得了更高的檢測性能和估計精度,"
             "改進算法在N=1 000時的性能仍然高于原算法在N=2 000下的性能。")
_GAINS = ("在同等粒子數的情況下TPFTBD相對原算法可以獲得1個dB以上的增益,"
          "而N=1 000下的TPFTBD相對原算法在N=2 000可以獲得0.5個dB左右的增益。")
_ZETA = ("TPFTBD在N=1000下,除了選擇ζ=0.4時,性能差于原PFTBD算法在N=2000下的性能外,"
         "其他情形下的性能都優于在N=2 000下的PFTBD算法。")

TPF_BETTER_6DB = Statement("claim", "§3.1, Figs. 1–3", _FIGS_1_3)
HALF_N_6DB = Statement("claim", "§3.1, Figs. 1–3", _FIGS_1_3)
GAIN_EQUAL_N = Statement("claim", "§3.2, Fig. 4", _GAINS)
GAIN_HALF_N = Statement("claim", "§3.2, Fig. 4", _GAINS)
GAIN_LOW_SNR = Statement("claim", "§3.2, Fig. 4",
                         "但是也會發現在很低信噪比(比如3 dB)以下通過增加粒子數或其他改進方法,"
                         "檢測與估計性能的提升效率也逐漸變小")
GAIN_HIGH_SNR = Statement("claim", "§3.2, Fig. 4",
                          "而在較高信噪比下,比如8 dB以上時,也發現第2階段的更新獲得的收益也變小,"
                          "特別是N=1 000下的TPFTBD相對優勢變小較多")
TIME_EQUAL_N = Statement("claim", "§3.2, Table 1", "在同等粒子數情況下改進算法計算量略有增加,約為10%~20%。")
TIME_HALF_N = Statement("claim", "§3.2, Table 1",
                        "但N=1000下的TPFTBD只需PFTBD 55%~60%左右的運算時間"
                        "就可以達到或者超過PFTBD在N=2 000的性能。")
ZETA_BEST = Statement("claim", "§3.3, Figs. 5 and 6",
                      "對于TPFTBD在其他轉移參數ζ下的性能,ζ=0.6時略優于ζ=0.9的情形,"
                      "而更多實驗可以證實ζ≤0.5的性能也逐漸下降,這與前面的定性分析基本吻合,"
                      "所以對于TPFTBD算法中可以選擇0.5<ζ<1,特別地可以選擇ζ=0.6。")
ONLY_ZETA_04_WORSE = Statement("claim", "§3.3, Fig. 5 (detection)", _ZETA)
ONLY_ZETA_04_WORSE_RMSE = Statement("claim", "§3.3, Fig. 6 (position error)", _ZETA)

#: claim slug (the part of the id after "tbd/") -> its statement
STATEMENTS: dict[str, Statement] = {
    "snr-gain-equal-n": GAIN_EQUAL_N,
    "snr-gain-half-n": GAIN_HALF_N,
    "gain-shrinks-low-snr": GAIN_LOW_SNR,
    "gain-shrinks-high-snr": GAIN_HIGH_SNR,
    "tpf-detects-better": TPF_BETTER_6DB,
    "tpf-more-accurate": TPF_BETTER_6DB,
    "half-n-detects-as-well": HALF_N_6DB,
    "half-n-more-accurate": HALF_N_6DB,
    "zeta-best": ZETA_BEST,
    "only-zeta-0.4-worse": ONLY_ZETA_04_WORSE,
    "only-zeta-0.4-worse-rmse": ONLY_ZETA_04_WORSE_RMSE,
    "time-equal-n": TIME_EQUAL_N,
    "time-half-n": TIME_HALF_N,
}
