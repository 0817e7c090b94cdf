"""numba's code generation for this processor, set once before gpfverify's compiled kernels
(:mod:`gpfverify.gp.fused_kernels`, :mod:`gpfverify.filters.sr_ukf_kernels`) are first compiled.

LLVM's tuning for Intel processors with AVX-512 (Skylake-X, Ice Lake, Rocket Lake, Sapphire
Rapids) prefers 256-bit vectors (the ``prefer-256-bit`` tuning feature) even where 512-bit
instructions exist, while numpy's vectorised ``exp`` uses the 512-bit ones: the moment kernel's
exponential loop then runs at half numpy's width (``benchmarks/bench_scale.py``, the
``predict_uncertain`` row: about 1.9 × numpy's exp with the tuning, about 1.5 × without, on an
AVX-512 Intel Xeon). :func:`configure` turns that preference off, keeping the processor's own
features otherwise.

It changes numba's process-wide ``CPU_FEATURES`` setting, so it acts only when nothing has decided
otherwise: not when the user set ``NUMBA_CPU_NAME`` or ``NUMBA_CPU_FEATURES`` (or numba's config
directly), not when numba has already compiled code in this process (its code generator is then
fixed), and not on processors without AVX-512. The setting is a tuning choice: the kernels' loops
are element-wise in a fixed order, so the vector width changes their speed, not their results
(tests/test_gp_fused.py compares the results under both settings).
"""

from __future__ import annotations

import os

#: the LLVM tuning feature turned off: "prefer 256-bit vectors over 512-bit ones"
_PREFER_256 = "prefer-256-bit"


def _numba_has_compiled() -> bool:
    """Whether numba's CPU code generator exists in this process (it is created by the first
    compilation and reads ``CPU_FEATURES`` only then)."""
    from numba.core.registry import cpu_target
    return "_toplevel_target_context" in vars(cpu_target)


def wider_vectors_features() -> str | None:
    """This processor's LLVM feature string with the 256-bit preference off, or None where the
    processor has no AVX-512 (nothing to widen)."""
    import llvmlite.binding as llvm

    features = llvm.get_host_cpu_features().flatten()
    if "+avx512f" not in features.split(","):
        return None
    return f"{features},-{_PREFER_256}"


def configure() -> bool:
    """Turn LLVM's 256-bit preference off for numba in this process where that is safe (module
    docstring); returns whether it did."""
    import numba

    user_chose = any(os.environ.get(name) for name in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES"))
    if user_chose or numba.config.CPU_NAME or numba.config.CPU_FEATURES or _numba_has_compiled():
        return False
    features = wider_vectors_features()
    if features is None:
        return False
    numba.config.CPU_FEATURES = features
    return True
