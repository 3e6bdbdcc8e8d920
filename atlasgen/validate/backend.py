"""Loading Mitsuba 3's ``llvm_ad_*`` variants, with one clear error when that is impossible."""

from __future__ import annotations

from atlasgen.errors import BackendError
from atlasgen.interrupts import deferred_interrupts

__all__ = ["load_mitsuba", "LLVM_HINT"]

#: What to install when Dr.Jit's LLVM backend cannot start.
LLVM_HINT = (
    "Mitsuba's LLVM backend is unavailable (Dr.Jit found no usable libLLVM); "
    "install libllvm19 (Debian/Ubuntu: apt-get install libllvm19), or point DRJIT_LIBLLVM_PATH at libLLVM.so"
)


def load_mitsuba(variant: str = "llvm_ad_rgb"):
    """Import Mitsuba, select ``variant`` and return the ``mitsuba`` module.

    Only ``llvm_ad_*`` variants are accepted: atlasgen's reference BSDFs are Python
    plugins, which Mitsuba supports in the JIT variants only (mitsuba3 issue 1093).

    Raises
    ------
    BackendError
        Mitsuba is not installed, the variant is missing, or Dr.Jit's LLVM backend
        cannot start (no libLLVM); the message says what to install.
    """
    if not variant.startswith("llvm_ad_"):
        raise ValueError(f"expected an llvm_ad_* variant, got {variant!r}")
    # A Ctrl-C during start-up is raised as KeyboardInterrupt once it is over, never as
    # the failure it would cause inside it (see atlasgen.interrupts).
    with deferred_interrupts():
        try:
            import drjit as dr
            import mitsuba as mi
        except ImportError as exc:
            raise BackendError(f"Mitsuba 3 is not installed ({exc}); install it with pip install 'atlasgen[mitsuba]'") from None
        if not dr.has_backend(dr.JitBackend.LLVM):
            raise BackendError(LLVM_HINT)
        if variant not in mi.variants():
            raise BackendError(f"this Mitsuba build has no variant {variant!r}; it has: {', '.join(mi.variants())}")
        try:
            mi.set_variant(variant)
        except (ImportError, RuntimeError) as exc:
            raise BackendError(f"{LLVM_HINT} ({str(exc).splitlines()[0]})") from None
    return mi
