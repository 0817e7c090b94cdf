"""Dimension-free proofs of the fusion claims (seed 000 Proposition 1 and SPEC §3) in the word
algebra of :mod:`gpfverify.symbolic.word_algebra`.

Sizes are symbols: n states (D), l outputs of sensor m (l_m), L = Σ l_m stacked outputs. What is
assumed is listed as rules and checked on exact rational instances of many sizes (sympy's exact
``Matrix.pinv`` for the pseudo-inverse):

* Penrose equations of A⁺ (A = C_xy^m): AA⁺A = A, A⁺AA⁺ = A⁺, (AA⁺)ᵀ = AA⁺, (A⁺A)ᵀ = A⁺A;
* C = C_y^m symmetric and invertible: Cᵀ = C, CC⁻¹ = C⁻¹C = I;
* the local update (eq. 32) as the definition of μ_e^m;
* full column rank as a hypothesis in its algebraic form "A has a left inverse", LA = I;
* the stacked gain and measurement as column/row blocks: G y = Σ_m G_m y^m (block product).

From these, lemmas are derived (P = A⁺A = I under full rank, P² = P, A(I − P) = 0), then the
claims. Each claim carries negative controls: mutated statements (a sign, a transpose, a wrong
inverse, a dropped term, a dropped hypothesis) that the same prover must reject, each also shown
false on an exact instance.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import numpy as np
import sympy as sp

from gpfverify.symbolic import word_algebra as wa
from gpfverify.symbolic.word_algebra import Mutant, Proof, Rule, identity, symbol, zero

n, l = sp.symbols("n l", integer=True, positive=True)
ONE = sp.Integer(1)

G = symbol("G_m", n, l)          # column block m of G = C_xy C_y⁻¹
C = symbol("C_y^m", l, l)        # local innovation covariance
Ci = symbol("C_y^m⁻¹", l, l)
A = symbol("C_xy^m", n, l)       # local cross covariance
Ap = symbol("C_xy^m⁺", l, n)     # its pseudo-inverse
Lf = symbol("L_m", l, n)         # a left inverse (full column rank hypothesis)
y = symbol("y^m", l, ONE)
my = symbol("μ_y^m", l, ONE)     # local predicted measurement
mc = symbol("μ_y(m)", l, ONE)    # central block
mp = symbol("μ_p^m", n, ONE)
me = symbol("μ_e^m", n, ONE)
v = symbol("v", l, ONE)
W = symbol("W", n, n)
I_l, I_n = identity(l), identity(n)
P = Ap * A                       # P_m = (C_xy^m)⁺ C_xy^m

SEED = 20191126


def _rule(name, lhs, rhs, kind):
    return Rule(name, lhs, rhs, kind)


PENROSE = [
    _rule("Penrose AA⁺A=A", A * Ap * A, A, "axiom"),
    _rule("Penrose A⁺AA⁺=A⁺", Ap * A * Ap, Ap, "axiom"),
    _rule("Penrose (AA⁺)ᵀ=AA⁺", (A * Ap).T, A * Ap, "axiom"),
    _rule("Penrose (A⁺A)ᵀ=A⁺A", (Ap * A).T, Ap * A, "axiom"),
]
C_RULES = [
    _rule("C_y^m symmetric", C.T, C, "hypothesis"),
    _rule("C_y^m⁻¹ symmetric", Ci.T, Ci, "hypothesis"),
    _rule("C C⁻¹=I", C * Ci, I_l, "hypothesis"),
    _rule("C⁻¹ C=I", Ci * C, I_l, "hypothesis"),
]
LOCAL_UPDATE = _rule("local update (eq. 32)", me, mp + A * Ci * (y - my), "definition")
LEFT_INVERSE = _rule("full column rank: L A = I", Lf * A, I_l, "hypothesis")


# ---- exact instances ------------------------------------------------------------------------------

#: (D, l_m, rank) of the instances; rank None = full column rank (needs l ≤ D).
INSTANCE_SHAPES = ((1, 1, None), (2, 1, None), (2, 2, None), (3, 2, None), (4, 3, None), (5, 2, None),
                   (2, 2, 1), (2, 3, 1), (3, 3, 2), (4, 5, 2), (3, 4, 1))


def _int_matrix(rng, rows, cols, lo=-3, hi=4):
    return sp.Matrix(rows, cols, lambda i, j: int(rng.integers(lo, hi)))


def fusion_instance(rng, d: int, outputs: int, rank: int | None, kernel_inclusion: bool = False) -> tuple:
    """Exact values of every letter, with the premises true: A of the given rank (random integer
    factors), A⁺ = sympy's exact pseudo-inverse, C = MMᵀ + I, μ_e^m from the local update, a left
    inverse when A has full column rank, G = W A C⁻¹ when ``kernel_inclusion``."""
    while True:
        if rank is None:
            a = _int_matrix(rng, d, outputs)
            if a.rank() == outputs:
                break
        else:
            a = _int_matrix(rng, d, rank) * _int_matrix(rng, outputs, rank).T
            if a.rank() == rank:
                break
    m = _int_matrix(rng, outputs, outputs)
    c = m * m.T + sp.eye(outputs)
    ci = c.inv()
    values = {"C_xy^m": a, "C_xy^m⁺": a.pinv(), "C_y^m": c, "C_y^m⁻¹": ci,
              "G_m": _int_matrix(rng, d, outputs), "y^m": _int_matrix(rng, outputs, 1),
              "μ_y^m": _int_matrix(rng, outputs, 1), "μ_y(m)": _int_matrix(rng, outputs, 1),
              "μ_p^m": _int_matrix(rng, d, 1), "v": _int_matrix(rng, outputs, 1), "W": _int_matrix(rng, d, d)}
    values["μ_e^m"] = values["μ_p^m"] + a * ci * (values["y^m"] - values["μ_y^m"])
    if rank is None:  # a left inverse, not the pseudo-inverse: A⁺ + Z(I − AA⁺) for a random Z
        values["L_m"] = values["C_xy^m⁺"] + _int_matrix(rng, outputs, d) * (sp.eye(d) - a * values["C_xy^m⁺"])
    if kernel_inclusion:
        values["G_m"] = values["W"] * a * ci
    return values, {n: d, l: outputs}


@cache
def _instances(full_rank, kernel_inclusion) -> tuple:
    rng = np.random.default_rng(SEED)
    out = []
    for d, outputs, rank in INSTANCE_SHAPES:
        if full_rank is not None and (rank is None) != full_rank:
            continue
        out.append(fusion_instance(rng, d, outputs, rank, kernel_inclusion))
    return tuple(out)


def instances(full_rank: bool | None = None, kernel_inclusion: bool = False) -> list[tuple]:
    """Instances over :data:`INSTANCE_SHAPES`: all of them, only full-rank (True) or only
    rank-deficient (False) ones (cached; the letter values are copied per call)."""
    return [(dict(values), sizes) for values, sizes in _instances(full_rank, kernel_inclusion)]


@dataclass
class Checked:
    """Every rule used, each with the verdict of its instance check (lemmas: their proof)."""

    rules: list[Rule]
    verdicts: dict = field(default_factory=dict)
    #: stated facts outside the algebra (name -> holds on its instance family), see :func:`rank_bound`
    facts: dict = field(default_factory=dict)

    @property
    def holds(self) -> bool:
        return all(self.verdicts.values()) and all(self.facts.values())

    def describe(self) -> list[str]:
        return ([f"{r.kind} {r.name}: {r.lhs} = {r.rhs}"
                 + ("" if r.kind == "lemma" else f" (exact instances: {'hold' if self.verdicts[r.name] else 'FAIL'})")
                 for r in self.rules]
                + [f"stated fact {name} (checked, not proved: {'holds' if ok else 'FAILS'} on every "
                   f"full-column-rank shape l_m ≤ D ≤ {FACT_MAX_D})" for name, ok in self.facts.items()])


def check_rules(rules: list[Rule], families: dict) -> Checked:
    """Axioms/hypotheses/definitions must hold on their instance family (``families``: rule name ->
    list of instances, default all); lemmas carry their proof and are also evaluated."""
    out = Checked(list(rules))
    for r in rules:
        out.verdicts[r.name] = wa.holds_on(r, families[r.name] if r.name in families else instances())
    return out


def planted_control(name: str, unsound: Rule, family: list[tuple]) -> wa.ControlResult:
    """A certificate holds only if every rule it uses holds on the instances of the rule's own
    hypotheses; planting ``unsound`` (a false rule, or a true one used outside its hypotheses) must
    make it fail. Rejected = the planted rule fails its check on ``family``."""
    checked = check_rules([unsound], {unsound.name: family})
    return wa.ControlResult(f"planted unsound rule: {name}", not checked.holds,
                            wa.counterexample(unsound.lhs, unsound.rhs, family))


PLANTED_TRANSPOSE = Rule("A⁺ = Aᵀ", Ap, A.T, "axiom")
PLANTED_FULL_RANK = Rule("A⁺A = I used on a rank-deficient C_xy^m", Ap * A, I_l, "axiom")


# ---- lemmas ---------------------------------------------------------------------------------------

def lemma_projector_is_identity() -> tuple[Rule, Proof]:
    """Full column rank (LA = I) ⇒ P = A⁺A = I: A⁺A = (LA)A⁺A = L(AA⁺A) = LA = I."""
    rules = PENROSE + [LEFT_INVERSE]
    proof = wa.prove_by_chain([(Ap * A, None), (Lf * A * Ap * A, LEFT_INVERSE.name),
                               (Lf * A, PENROSE[0].name), (I_l, LEFT_INVERSE.name)], rules,
                              "A⁺A = I when A has a left inverse")
    return wa.lemma("P=I (full rank)", proof, Ap * A, I_l), proof


def lemma_idempotent() -> tuple[Rule, Proof]:
    proof = wa.prove_by_normal_form(P * P, P, PENROSE, "P² = P")
    return wa.lemma("P²=P", proof, Ap * A * Ap * A, Ap * A), proof


def lemma_kernel_projector() -> tuple[Rule, Proof]:
    proof = wa.prove_by_normal_form(A * (I_l - P), zero(n, l), PENROSE, "A(I − P) = 0")
    return wa.lemma("A(I−P)=0", proof, A * Ap * A, A), proof


# ---- statements -----------------------------------------------------------------------------------

def dmf_term(gain=G, cov=C, pinv=Ap, posterior=me, local_mean=my, central=mc, prior=mp):
    """Sensor m's share of μ_DMF − μ_p (eq. 35)."""
    return gain * (local_mean - central) + gain * cov * pinv * (posterior - prior)


def cmf_term(gain=G, meas=y, central=mc):
    """Sensor m's share of μ_CMF − μ_p (eq. 15 with G split into column blocks)."""
    return gain * (meas - central)


def gap_term(gain=G, cov=C, proj=P, inv=Ci, meas=y, local_mean=my):
    return gain * cov * (proj - I_l) * inv * (meas - local_mean)


# ---- the N-sensor statement with explicit blocks --------------------------------------------------

def stacked(n_sensors: int):
    """Symbols of an N-sensor step: central G (n × L), y, μ_y (L × 1) and per sensor m the letters
    of one sensor with index m; block-product rules G y = Σ G_m y^m, G μ_y = Σ G_m μ_y(m)."""
    sizes = [sp.Symbol(f"l{m}", integer=True, positive=True) for m in range(n_sensors)]
    total = sp.Symbol("L", integer=True, positive=True)
    big_g, big_y, big_mu = symbol("G", n, total), symbol("y", total, ONE), symbol("μ_y", total, ONE)
    mu_p = symbol("μ_p", n, ONE)
    sensors = []
    for m, lm in enumerate(sizes):
        s = {k: symbol(f"{k}[{m}]", r, c) for k, (r, c) in {
            "G": (n, lm), "C": (lm, lm), "Ci": (lm, lm), "A": (n, lm), "Ap": (lm, n), "Lf": (lm, n),
            "y": (lm, ONE), "my": (lm, ONE), "mc": (lm, ONE), "mp": (n, ONE), "me": (n, ONE)}.items()}
        sensors.append(s)
    block_y = Rule(f"block product G y = Σ G_m y^m (N = {n_sensors})", big_g * big_y,
                   sum((s["G"] * s["y"] for s in sensors[1:]), sensors[0]["G"] * sensors[0]["y"]), "axiom")
    block_mu = Rule(f"block product G μ_y = Σ G_m μ_y(m) (N = {n_sensors})", big_g * big_mu,
                    sum((s["G"] * s["mc"] for s in sensors[1:]), sensors[0]["G"] * sensors[0]["mc"]), "axiom")
    per_sensor = []
    for m, s in enumerate(sensors):
        lm = sizes[m]
        per_sensor += [
            Rule(f"C[{m}] C[{m}]⁻¹=I", s["C"] * s["Ci"], identity(lm), "hypothesis"),
            Rule(f"local update[{m}]", s["me"], s["mp"] + s["A"] * s["Ci"] * (s["y"] - s["my"]), "definition"),
            Rule(f"Penrose AA⁺A=A [{m}]", s["A"] * s["Ap"] * s["A"], s["A"], "axiom"),
            Rule(f"full column rank [{m}]", s["Lf"] * s["A"], identity(lm), "hypothesis"),
        ]
    dmf = mu_p + sum((s["G"] * (s["my"] - s["mc"]) + s["G"] * s["C"] * s["Ap"] * (s["me"] - s["mp"])
                      for s in sensors[1:]),
                     sensors[0]["G"] * (sensors[0]["my"] - sensors[0]["mc"])
                     + sensors[0]["G"] * sensors[0]["C"] * sensors[0]["Ap"] * (sensors[0]["me"] - sensors[0]["mp"]))
    cmf = mu_p + big_g * (big_y - big_mu)
    gap = sum((s["G"] * s["C"] * (s["Ap"] * s["A"] - identity(lm)) * s["Ci"] * (s["y"] - s["my"])
               for s, lm in list(zip(sensors, sizes))[1:]),
              sensors[0]["G"] * sensors[0]["C"] * (sensors[0]["Ap"] * sensors[0]["A"] - identity(sizes[0]))
              * sensors[0]["Ci"] * (sensors[0]["y"] - sensors[0]["my"]))
    return dict(sensors=sensors, sizes=sizes, block=[block_y, block_mu], per_sensor=per_sensor,
                dmf=dmf, cmf=cmf, gap=gap)


def stacked_full_rank_rules(st) -> list[Rule]:
    """Per-sensor P = I derived in the stacked symbols (the same chain as the one-sensor lemma)."""
    out = []
    for m, s in enumerate(st["sensors"]):
        rules = [r for r in st["per_sensor"] if r.name.endswith(f"[{m}]") or f"[{m}]" in r.name]
        pen = next(r for r in rules if r.name.startswith("Penrose"))
        left = next(r for r in rules if r.name.startswith("full column rank"))
        lm = st["sizes"][m]
        proof = wa.prove_by_chain([(s["Ap"] * s["A"], None), (s["Lf"] * s["A"] * s["Ap"] * s["A"], left.name),
                                   (s["Lf"] * s["A"], pen.name), (identity(lm), left.name)], rules)
        out.append(wa.lemma(f"P=I [{m}]", proof, s["Ap"] * s["A"], identity(lm)))
    return out


def stacked_instance(rng, dims: int, outputs: tuple, full_rank: bool) -> tuple:
    d = dims
    values, sizes = {}, {n: d}
    blocks_g, blocks_y, blocks_mu = [], [], []
    for m, lm in enumerate(outputs):
        vals, _ = fusion_instance(rng, d, lm, None if full_rank else max(1, min(d, lm) - 1))
        key = {"G_m": "G", "C_y^m": "C", "C_y^m⁻¹": "Ci", "C_xy^m": "A", "C_xy^m⁺": "Ap", "L_m": "Lf",
               "y^m": "y", "μ_y^m": "my", "μ_y(m)": "mc", "μ_p^m": "mp", "μ_e^m": "me"}
        for k, short in key.items():
            if k in vals:
                values[f"{short}[{m}]"] = vals[k]
        sizes[sp.Symbol(f"l{m}", integer=True, positive=True)] = lm
        blocks_g.append(vals["G_m"])
        blocks_y.append(vals["y^m"])
        blocks_mu.append(vals["μ_y(m)"])
    values["G"] = sp.Matrix.hstack(*blocks_g)
    values["y"] = sp.Matrix.vstack(*blocks_y)
    values["μ_y"] = sp.Matrix.vstack(*blocks_mu)
    values["μ_p"] = _int_matrix(rng, d, 1)
    sizes[sp.Symbol("L", integer=True, positive=True)] = sum(outputs)
    return values, sizes


STACKED_SHAPES = {2: ((2, (2, 1)), (3, (2, 2)), (4, (1, 3))), 3: ((3, (1, 2, 3)), (2, (1, 1, 2)))}


# ---- claims ---------------------------------------------------------------------------------------

@dataclass
class DimensionFreeResult:
    """What a certificate needs: the proofs, the rules (checked), the controls, the scope."""

    proofs: list[Proof]
    checked: Checked
    controls: list
    scope: str

    @property
    def hypotheses(self) -> frozenset:
        """The certificate's hypotheses: the hypothesis rules it lists and checks on instances."""
        return frozenset(r.name for r in self.checked.rules if r.kind == "hypothesis")

    @property
    def outside_hypotheses(self) -> list[str]:
        """Proofs resting on a hypothesis the certificate does not state (a rule used outside its
        hypotheses, e.g. the full-rank lemma P = I in a statement about any rank)."""
        return [p.statement for p in self.proofs if not p.premises <= self.hypotheses]

    @property
    def holds(self) -> bool:
        return all(p.proved for p in self.proofs) and self.checked.holds and not self.outside_hypotheses

    @property
    def controls_rejected(self) -> bool:
        return all(c.rejected for c in self.controls)

    def describe(self) -> str:
        proofs = "; ".join(f"[{'proved' if p.proved else 'NOT PROVED'}] {p.statement}: {p.trace}" for p in self.proofs)
        rules = "; ".join(self.checked.describe())
        controls = "; ".join(f"{c.mutant}: {'rejected' if c.rejected else 'ACCEPTED'}"
                             + ("" if c.false_on_instance is None else
                                f" ({'false' if c.false_on_instance else 'not false'} on an exact instance)")
                             for c in self.controls)
        return f"Rules: {rules}. Proofs: {proofs}. Negative controls: {controls}."


def _nf(lhs, rhs, rules, statement=""):
    return lambda: wa.prove_by_normal_form(lhs, rhs, rules, statement)


def _stacked_proofs(statement_rhs: str, full_rank: bool) -> tuple[list[Proof], list[Rule], dict[str, list[tuple]]]:
    """μ_DMF − μ_CMF reduced for N = 2 and 3 explicit sensors (block product rules)."""
    proofs: list[Proof] = []
    rules_all: list[Rule] = []
    families: dict[str, list[tuple]] = {}
    rng = np.random.default_rng(SEED + 1)
    for count in (2, 3):
        st = stacked(count)
        rules = st["block"] + st["per_sensor"]
        if full_rank:
            rules = rules + stacked_full_rank_rules(st)
            target = zero(n, ONE)
        else:
            rules = [r for r in rules if not r.name.startswith("full column rank")]
            target = st["gap"]
        proofs.append(wa.prove_by_normal_form(st["dmf"] - st["cmf"], target, rules,
                                              f"N = {count}: μ_DMF − μ_CMF = {statement_rhs}"))
        inst = [stacked_instance(rng, d, outs, full_rank) for d, outs in STACKED_SHAPES[count]
                if not (full_rank and max(outs) > d)]
        for r in rules:
            if r.kind != "lemma" and "[" in r.name or "block" in r.name:
                if r.name.startswith("block") or r.name not in families:
                    families[r.name] = inst
        rules_all += [r for r in rules if r not in rules_all]
    return proofs, rules_all, families


# ---- any N: induction over the number of sensors --------------------------------------------------

K = sp.Symbol("K", integer=True, positive=True)   # outputs of the first N sensors together
G_first, y_first, mu_first = symbol("G_(N)", n, K), symbol("y_(N)", K, ONE), symbol("μ_y(N)", K, ONE)
G_next, y_next, mu_next = symbol("G_(N+1)", n, K + l), symbol("y_(N+1)", K + l, ONE), symbol("μ_y(N+1)", K + l, ONE)
dmf_first = symbol("Σ_{m≤N} DMF_m", n, ONE)       # the first N sensors' share of μ_DMF − μ_p
gap_first = symbol("Σ_{m≤N} gap_m", n, ONE)
BLOCKS = [Rule("block product G_(N+1) y_(N+1) = G_(N) y_(N) + G_m y^m", G_next * y_next,
               G_first * y_first + G * y, "axiom"),
          Rule("block product G_(N+1) μ_y(N+1) = G_(N) μ_y(N) + G_m μ_y(m)", G_next * mu_next,
               G_first * mu_first + G * mc, "axiom")]


def induction_instances(with_gap: bool) -> list[tuple]:
    """Instances of the induction step: a sensor instance, N sensors' blocks of K = 1..3 outputs
    (random), the N + 1 sensors' blocks stacked from both, the induction hypothesis made true."""
    rng = np.random.default_rng(SEED + 3)
    out = []
    for k, (values, sizes) in enumerate(instances()):
        d = sizes[n]
        first = 1 + k % 3
        vals = dict(values, **{"G_(N)": _int_matrix(rng, d, first), "y_(N)": _int_matrix(rng, first, 1),
                               "μ_y(N)": _int_matrix(rng, first, 1), "Σ_{m≤N} gap_m": _int_matrix(rng, d, 1)})
        vals["G_(N+1)"] = sp.Matrix.hstack(vals["G_(N)"], vals["G_m"])
        vals["y_(N+1)"] = sp.Matrix.vstack(vals["y_(N)"], vals["y^m"])
        vals["μ_y(N+1)"] = sp.Matrix.vstack(vals["μ_y(N)"], vals["μ_y(m)"])
        vals["Σ_{m≤N} DMF_m"] = (vals["G_(N)"] * (vals["y_(N)"] - vals["μ_y(N)"])
                                 + (vals["Σ_{m≤N} gap_m"] if with_gap else sp.zeros(d, 1)))
        out.append((vals, {**sizes, K: first}))
    return out


def induction_step(per_sensor: list[Rule], with_gap: bool) -> tuple[Proof, list[Rule], list[tuple]]:
    """From N to N + 1 sensors: if the first N sensors' DMF terms sum to G_(N)(y_(N) − μ_y(N))
    (+ their gaps), adding sensor m (``per_sensor``: the rules of the one-sensor proof) gives
    G_(N+1)(y_(N+1) − μ_y(N+1)) (+ the gaps and gap_m). With N = 1 (the one-sensor proof) as the
    base, this is the statement for every N."""
    gaps = gap_first if with_gap else zero(n, ONE)
    hypothesis = Rule("induction hypothesis (N sensors)", dmf_first,
                      G_first * (y_first - mu_first) + gaps, "hypothesis")
    rules = per_sensor + BLOCKS + [hypothesis]
    lhs = dmf_first + dmf_term()
    rhs = G_next * (y_next - mu_next) + gaps + (gap_term() if with_gap else zero(n, ONE))
    proof = wa.prove_by_normal_form(lhs, rhs, rules, "induction step N → N + 1 sensors: Σ_{m≤N+1} DMF_m = "
                                    + ("G_(N+1)(y_(N+1) − μ_y(N+1)) + Σ_{m≤N+1} gap_m" if with_gap
                                       else "G_(N+1)(y_(N+1) − μ_y(N+1))"))
    return proof, BLOCKS + [hypothesis], induction_instances(with_gap)


def prop1() -> DimensionFreeResult:
    p_is_i, p_proof = lemma_projector_is_identity()
    rules = PENROSE + C_RULES + [LOCAL_UPDATE, LEFT_INVERSE]
    main_rules = C_RULES + [LOCAL_UPDATE, p_is_i]
    main = wa.prove_by_normal_form(dmf_term(), cmf_term(), main_rules, "DMF_m = CMF_m for a generic sensor m")
    stacked_proofs, stacked_rules, stacked_families = _stacked_proofs("0", full_rank=True)
    step, step_rules, step_instances = induction_step(main_rules, with_gap=False)
    full = instances(full_rank=True)
    full_step = [i for i in step_instances if i[1][n] >= i[0]["C_y^m"].shape[0]]
    families = {LEFT_INVERSE.name: full, **stacked_families, **{r.name: full_step for r in step_rules}}
    checked = check_rules(rules + [p_is_i] + step_rules + [r for r in stacked_rules if r.kind != "lemma"],
                          {**families, p_is_i.name: full})
    deficient = instances(full_rank=False)
    mutants = [
        Mutant("A⁺ replaced by Aᵀ in eq. 35", _nf(dmf_term(pinv=A.T), cmf_term(), main_rules),
               dmf_term(pinv=A.T), cmf_term()),
        Mutant("sign of G_m(μ_y^m − μ_y(m)) flipped", _nf(
            dmf_term() - 2 * (G * (my - mc)), cmf_term(), main_rules), dmf_term() - 2 * (G * (my - mc)), cmf_term()),
        Mutant("G_m(μ_y^m − μ_y(m)) dropped", _nf(dmf_term() - G * (my - mc), cmf_term(), main_rules),
               dmf_term() - G * (my - mc), cmf_term()),
        Mutant("C_y^m replaced by (C_y^m)⁻¹ in eq. 35", _nf(dmf_term(cov=Ci), cmf_term(), main_rules),
               dmf_term(cov=Ci), cmf_term()),
        Mutant("local update with C_y^m in place of (C_y^m)⁻¹",
               _nf(dmf_term(posterior=mp + A * C * (y - my)), cmf_term(), main_rules),
               dmf_term(posterior=mp + A * C * (y - my)), cmf_term()),
    ]
    controls = wa.run_controls(mutants, full)
    # dropping the hypothesis: the same statement without P = I, false on rank-deficient instances
    controls += wa.run_controls([Mutant("full-column-rank hypothesis dropped",
                                        _nf(dmf_term(), cmf_term(), C_RULES + [LOCAL_UPDATE] + PENROSE),
                                        dmf_term(), cmf_term())], deficient)
    controls.append(planted_control("A⁺ = Aᵀ (proves the first mutant)", PLANTED_TRANSPOSE, full))
    controls.append(planted_control("P = I outside full column rank", PLANTED_FULL_RANK, deficient))
    return DimensionFreeResult([p_proof, main, step] + stacked_proofs, checked, controls, "any dimension")


def gap_formula() -> DimensionFreeResult:
    rules = C_RULES + [LOCAL_UPDATE]
    main = wa.prove_by_normal_form(dmf_term() - cmf_term(), gap_term(), rules,
                                   "DMF_m − CMF_m = G_m C_y^m (P_m − I)(C_y^m)⁻¹(y^m − μ_y^m), any C_xy^m")
    stacked_proofs, stacked_rules, families = _stacked_proofs("Σ_m gap_m", full_rank=False)
    step, step_rules, step_instances = induction_step(rules, with_gap=True)
    families.update({r.name: step_instances for r in step_rules})
    checked = check_rules(rules + PENROSE + step_rules + [r for r in stacked_rules if r.kind != "lemma"], families)
    lhs = dmf_term() - cmf_term()
    cases = {
        "(I − P) in place of (P − I)": gap_term(proj=2 * I_l - P),
        "(C_y^m)⁻¹ replaced by C_y^m": gap_term(inv=C),
        "A⁺ replaced by Aᵀ in P": gap_term(proj=A.T * A),
        "C_y^m factor dropped": G * (P - I_l) * Ci * (y - my),
        "innovation against μ_y(m) instead of μ_y^m": gap_term(local_mean=mc),
        "sign of the gap flipped": -gap_term(),
    }
    mutants = [Mutant(k, _nf(lhs, rhs, rules), lhs, rhs) for k, rhs in cases.items()]
    controls = wa.run_controls(mutants, instances(full_rank=False))
    controls.append(planted_control("P = I outside full column rank (makes every gap 0)", PLANTED_FULL_RANK,
                                    instances(full_rank=False)))
    return DimensionFreeResult([main, step] + stacked_proofs, checked, controls, "any dimension")


def kernel_inclusion() -> DimensionFreeResult:
    idem, idem_proof = lemma_idempotent()
    kern, kern_proof = lemma_kernel_projector()
    x_zero = Rule("hypothesis X_m = G_m C_y^m (I − P_m) = 0", G * C * Ap * A, G * C, "hypothesis")
    chosen = Rule("chosen measurement y^m = μ_y^m + C_y^m (I − P_m) v", y, my + C * (I_l - P) * v, "definition")
    in_kernel = Rule("v ∈ ker C_xy^m", A * v, zero(n, ONE), "hypothesis")
    x_v = G * C * (I_l - P) * v
    sufficiency = wa.prove_by_normal_form(gap_term(), zero(n, ONE), C_RULES + [x_zero],
                                          "sufficiency: X_m = 0 ⇒ gap_m = 0 for every y^m")
    necessity_rules = C_RULES + [chosen, idem]
    necessity = wa.prove_by_normal_form(gap_term(), -x_v, necessity_rules,
                                        "necessity: at y^m = μ_y^m + C_y^m(I − P_m)v, gap_m = −X_m v (so gap ≡ 0 "
                                        "for every y forces X_m v = 0 for every v, i.e. X_m = 0)")
    kernel_fwd = wa.prove_by_chain([(G * C * v, None), (G * C * Ap * A * v, x_zero.name),
                                    (zero(n, ONE), in_kernel.name)],
                                   [x_zero, in_kernel],
                                   "X_m = 0 ⇒ ker C_xy^m ⊆ ker G_m C_y^m: "
                                   "G_m C_y^m v = G_m C_y^m P_m v = 0 for A v = 0")
    # ⇐: A(I − P)w = 0 for every w (lemma A(I−P)=0), so (I − P)w ∈ ker A ⊆ ker G C and X w = 0.
    # instance families: X_m = 0 holds for G = W A C⁻¹; a kernel vector v of a deficient A
    incl = instances(kernel_inclusion=True)
    kern_inst = []
    for vals, sizes in instances(full_rank=False):
        a = vals["C_xy^m"]
        kern_inst.append((dict(vals, v=a.nullspace()[0]), sizes))
    chosen_inst = []
    for vals, sizes in instances():
        vals = dict(vals)
        proj = vals["C_xy^m⁺"] * vals["C_xy^m"]
        vals["y^m"] = vals["μ_y^m"] + vals["C_y^m"] * (sp.eye(proj.shape[0]) - proj) * vals["v"]
        chosen_inst.append((vals, sizes))
    checked = check_rules(PENROSE + C_RULES + [x_zero, chosen, in_kernel, idem, kern],
                          {x_zero.name: incl, chosen.name: chosen_inst, in_kernel.name: kern_inst})
    mutants = [
        Mutant("necessity with the sign of X_m v flipped", _nf(gap_term(), x_v, necessity_rules),
               gap_term(), x_v),
        Mutant("necessity with direction C_y^m⁻¹(I − P_m)v",
               _nf(gap_term(meas=my + Ci * (I_l - P) * v), -x_v, C_RULES + [idem]),
               gap_term(meas=my + Ci * (I_l - P) * v), -x_v),
        Mutant("necessity with P_m replaced by C_xyᵀC_xy",
               _nf(gap_term(proj=A.T * A), -G * C * (I_l - A.T * A) * v, C_RULES + [chosen, idem]),
               gap_term(proj=A.T * A), -G * C * (I_l - A.T * A) * v),
        Mutant("sufficiency from the weaker G_m(I − P_m) = 0",
               _nf(gap_term(), zero(n, ONE), C_RULES + [Rule("G P = G", G * Ap * A, G, "hypothesis")]),
               gap_term(), zero(n, ONE)),
        Mutant("sufficiency with the hypothesis dropped", _nf(gap_term(), zero(n, ONE), C_RULES + PENROSE),
               gap_term(), zero(n, ONE)),
        Mutant("kernel inclusion with C_y^m dropped (ker A ⊆ ker G_m)",
               lambda: wa.prove_by_chain([(G * v, None), (G * Ap * A * v, x_zero.name), (zero(n, ONE), in_kernel.name)],
                                         [x_zero, in_kernel]), G * v, zero(n, ONE)),
    ]
    # X_m = 0 (G = W A C⁻¹) with v in the kernel of a rank-deficient A: G v = W A C⁻¹ v is not 0
    incl_kern = [(dict(vals, v=vals["C_xy^m"].nullspace()[0]), sizes)
                 for vals, sizes in instances(full_rank=False, kernel_inclusion=True)]
    controls = wa.run_controls(mutants[:3], chosen_inst)
    controls += wa.run_controls(mutants[3:5], instances(full_rank=False)) + wa.run_controls(mutants[5:], incl_kern)
    controls.append(planted_control("P = I outside full column rank (X_m = 0 for every G_m)", PLANTED_FULL_RANK,
                                    kern_inst))
    return DimensionFreeResult([idem_proof, kern_proof, sufficiency, necessity, kernel_fwd], checked, controls,
                               "any dimension")


#: the stated facts about trace and rank are checked on every full-column-rank shape up to this D
FACT_MAX_D = 5


@cache
def _every_full_rank_shape() -> tuple:
    rng = np.random.default_rng(SEED + 2)
    return tuple(fusion_instance(rng, d, outputs, None) for d in range(1, FACT_MAX_D + 1)
                 for outputs in range(1, d + 1))


def every_full_rank_shape() -> list[tuple]:
    """Instances of the hypothesis "C_xy^m has full column rank" at every shape l_m ≤ D ≤
    :data:`FACT_MAX_D` (a fact is checked on all shapes its hypothesis allows, not on a few)."""
    return [(dict(values), sizes) for values, sizes in _every_full_rank_shape()]


def rank_bound(bound, bound_text: str) -> DimensionFreeResult:
    """Full column rank ⇒ l_m ≤ ``bound(D)``: LA = I (A n×l) ⇒ E = AL is idempotent (n×n), proved
    by rewriting; then l = tr(I_l) = tr(LA) = tr(AL) = tr E = rank E ≤ bound(D) is a stated fact
    (trace cyclic, trace of an idempotent = its rank, rank ≤ D), checked on every full-column-rank
    shape D ≤ :data:`FACT_MAX_D`, so the conclusion is checked there, not proved for every D.
    ``bound(D) = D`` is the claim; any smaller bound is false and fails the check."""
    e = A * Lf
    idem = wa.prove_by_normal_form(e * e, e, [LEFT_INVERSE], "E = A L is idempotent: (AL)(AL) = A(LA)L = AL")
    every = every_full_rank_shape()
    fact = (f"l_m = tr(I_l) = tr(LA) = tr(AL) = rank(AL) ≤ {bound_text} (trace cyclic, trace of an "
            "idempotent = its rank)")
    fact_holds = all(vals["L_m"].shape[0] == (vals["L_m"] * vals["C_xy^m"]).trace()
                     == (vals["C_xy^m"] * vals["L_m"]).trace() == (vals["C_xy^m"] * vals["L_m"]).rank()
                     <= bound(vals["C_xy^m"].shape[0]) for vals, _ in every)
    checked = check_rules([LEFT_INVERSE], {LEFT_INVERSE.name: every})
    checked.facts[fact] = fact_holds
    mutants = [
        Mutant("(AL)(AL) = I_D (AL the identity)", _nf(e * e, I_n, [LEFT_INVERSE]), e * e, I_n),
        Mutant("(AL)ᵀ = AL (AL symmetric)", _nf(e.T, e, [LEFT_INVERSE]), e.T, e),
        Mutant("idempotence with the hypothesis dropped", _nf(e * e, e, PENROSE), e * e, e),
    ]
    full = instances(full_rank=True)
    controls = wa.run_controls(mutants[:2], [i for i in full if i[1][n] > i[1][l]])
    controls += wa.run_controls(mutants[2:3], [(dict(vals, L_m=_int_matrix(np.random.default_rng(SEED),
                                                                           *vals["L_m"].shape)), s)
                                               for vals, s in full])
    controls.append(planted_control("AL = I_D (a left inverse taken for a right inverse)",
                                    Rule("AL = I_D", e, I_n, "axiom"), every))
    return DimensionFreeResult([idem], checked, controls, f"checked on D ≤ {FACT_MAX_D}")


def l_le_d() -> DimensionFreeResult:
    """Full column rank ⇒ l_m ≤ D (:func:`rank_bound` with the bound D)."""
    return rank_bound(lambda d: d, "D")
