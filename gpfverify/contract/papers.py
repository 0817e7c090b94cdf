"""The source papers, cited in full: report pages and claim records refer to them by key."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Paper:
    key: str
    authors: str
    title: str
    #: the title in English, for papers written in Chinese
    title_en: str
    venue: str
    year: int
    #: how the pages refer to it in running text
    short: str

    @property
    def citation(self) -> str:
        english = f" ({self.title_en})" if self.title_en and self.title_en != self.title else ""
        return f"{self.authors}. {self.title}{english}. {self.venue}, {self.year}."


PAPERS: dict[str, Paper] = {p.key: p for p in (
    Paper("seed000", "Yiwei Liao, Jiangqiong Xie, Zhiguo Wang, Xiaojing Shen",
          "Multisensor Estimation Fusion with Gaussian Process for Nonlinear Dynamic Systems",
          "Multisensor Estimation Fusion with Gaussian Process for Nonlinear Dynamic Systems",
          "Entropy 21(11), 1126", 2019, "Liao et al. 2019"),
    Paper("seed001", "Meng Yang (孟阳), Gao Shesheng (高社生), Wang Wei (王维)",
          "基于高斯过程回归的平方根UPF算法",
          "A square-root unscented particle filter based on Gaussian process regression",
          "Systems Engineering and Electronics (系统工程与电子技术) 37(12), 2817–2822", 2015, "Meng et al. 2015"),
    Paper("seed003", "Zhou Deyun (周德运), Liu Bin (刘斌), Su Qian (苏茜)",
          "基于“新息误差”的粒子流滤波算法",
          "A particle flow filter based on the innovation error",
          "Journal of Computer Applications (计算机应用) 2020(11)", 2020, "Zhou et al. 2020"),
    Paper("seed004", "Chen Yanjun (陈延军), Liang Xinhua (梁新华), Pan Quan (潘泉), Liang Yan (梁彦)",
          "两级量测更新的粒子滤波检测前跟踪算法",
          "A particle-filter track-before-detect algorithm with a two-stage measurement update",
          "Chinese Journal of Sensors and Actuators (传感技术学报) 2015(1)", 2015, "Chen et al. 2015"),
    # the GP-ADF filter and its scalar benchmark, reference [7] of the fusion paper
    Paper("deisenroth2009", "Marc Peter Deisenroth, Marco F. Huber, Uwe D. Hanebeck",
          "Analytic Moment-based Gaussian Process Filtering", "Analytic Moment-based Gaussian Process Filtering",
          "Proceedings of the 26th International Conference on Machine Learning (ICML), 225–232", 2009,
          "Deisenroth et al. 2009"),
)}
