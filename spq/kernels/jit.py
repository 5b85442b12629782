"""The one decorator every compiled kernel uses.

cache=True keeps compiled code between runs; error_model="numpy" makes a float division by zero
give inf/nan instead of a Python exception check on every division in the hot loops (the kernels
test their denominators themselves).

Kernels run without numba's reference counting (NRT) unless they allocate. With it, every array
passed to a non-inlined call, and every view taken, costs an increment and a decrement call: in a
scene's all-pairs call, where a query is a chain of small calls with a dozen array arguments each,
those calls took about a fifth of the time (measured with perf). A kernel without NRT cannot
allocate, so the hot paths take scratch arrays from their callers; a kernel that does allocate (an
entry point that returns new arrays) says so with ``allocates=True`` and may call the others, but
not the other way round. Nor may code with NRT (a kernel with ``allocates=True``, or a user's own
``njit``) keep an array that a kernel without it returns (hull_core's views): it would release a
reference it never took.

Inlining a large kernel saves its call (a dozen arrays passed) but copies its code into every entry
point that reaches it, and each copy is compiled again. ``inline="hot"`` inlines a kernel only into
the entry points marked ``hot=True`` (a robot scene's all-pairs loop, where the calls' cost shows);
everywhere else it stays a call, which keeps the other entry points' compile time down.

numba stamps a cached function with a hash of its own file only, read when the cache is written. A
kernel that inlines (or calls, compiled into one module) a kernel from another file kept its old
machine code after that file changed, and a process still running old code stamped what it wrote
with the new file's hash. So every kernel's cache here is stamped with one digest of all the
kernels' sources, taken once at import (:data:`KERNELS_DIGEST`): any change to any kernel file, or a
process from before it, makes every cached kernel stale and compiled anew.

Importing this module also makes numba's copies of an inlined kernel's IR linear in its size
(:func:`_install_shared_scope_copies`): they were a third of compiling an entry point.
"""

import collections
import copy
import hashlib
import os
from pathlib import Path

from numba import njit, types

KERNELS_DIR = Path(__file__).resolve().parent


def _sources_digest(folder: Path) -> str:
    """sha256 over the names and contents of the folder's *.py files (the kernels import nothing else)."""
    h = hashlib.sha256()
    for path in sorted(folder.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


KERNELS_DIGEST = _sources_digest(KERNELS_DIR)


def _install_cache_stamp() -> None:
    """Put locators stamping with KERNELS_DIGEST ahead of numba's own, for files in KERNELS_DIR only:
    the same cache folders (NUMBA_CACHE_DIR, __pycache__, then the user-wide one) as numba's."""
    try:
        from numba.core import caching
    except ImportError:  # a numba without this module: its own per-file stamps stay
        return
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    bases = [getattr(caching, name, None) for name in
             ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")]
    if impl is None or not isinstance(getattr(impl, "_locator_classes", None), list) or None in bases:
        return
    # keyed by this folder: a second copy of the package in the same process (a same-process A/B
    # against an older spq) installs its own, or its kernels would fall back to numba's per-file stamps
    if any(getattr(c, "_spq_kernels", None) == KERNELS_DIR for c in impl._locator_classes):
        return

    class _KernelsStamp:
        _spq_kernels = KERNELS_DIR

        @classmethod
        def from_function(cls, py_func, py_file):
            try:
                if Path(py_file).resolve().parent != KERNELS_DIR:
                    return None
            except OSError:
                return None
            return super().from_function(py_func, py_file)

        def get_source_stamp(self):
            return KERNELS_DIGEST

    ours = [type(f"Kernels{base.__name__}", (_KernelsStamp, base), {}) for base in bases]
    impl._locator_classes[:0] = ours


_install_cache_stamp()


def _in_kernels_dir(function) -> bool:
    """Whether a Python function is defined in a file of this folder (a kernel)."""
    try:
        return Path(function.__code__.co_filename).resolve().parent == KERNELS_DIR
    except (AttributeError, OSError):
        return False


def _install_shared_scope_copies() -> None:
    """Make numba's IR inliner copy a kernel's IR in linear time, and build it once per kernel.

    For each ``inline="always"`` call site, numba (0.68) builds the callee's IR afresh (its untyped
    passes, nested inlining included) and copies it block by block with ``copy.deepcopy``, a fresh
    memo for each block. Every variable's copy then copies its Scope, and with it every variable of
    the function, once per block: in an entry point that inlines the whole query, those copies were
    a third of the compile (py-spy). The inliner only reads that scope and adds the inlined names to
    it (it renames every variable into the caller's scope), so while it inlines a function here, a
    variable's copy takes a copy of the Scope made once for that call site.

    A kernel of this folder is built once and its IR kept (the inliner copies it before changing
    anything, and the scope it would grow is the per-site copy): rebuilding it at every one of the
    thousands of call sites was an eighth of the first spq.distance's compile. Its IR depends only on
    the function and the compiler's flags, as the kernels' globals are constants. Other code's
    inlined functions (a user's, whose globals may change between two compiles) are built afresh at
    each call site, as numba does.

    Only InlineWorker.inline_function (the ``inline=`` option of njit kernels) is changed; an
    overload's cached IR, inlined by inline_ir directly, is copied as before. The compiled code is
    the same (tests/test_jit.py compares results and LLVM IR with and without it).
    SPQ_NUMBA_INLINE_COPY=stock leaves numba as it is."""
    if os.environ.get("SPQ_NUMBA_INLINE_COPY", "") == "stock":
        return
    try:
        from numba.core import ir
        from numba.core.inline_closurecall import InlineWorker
    except ImportError:
        return
    inline_function = getattr(InlineWorker, "inline_function", None)
    if inline_function is None or getattr(inline_function, "_spq_shared_scope", False):
        return
    var_copy = ir.Var.__dict__.get("__deepcopy__")
    if var_copy is None or "__deepcopy__" in ir.Scope.__dict__ or not hasattr(InlineWorker, "run_untyped_passes"):
        return  # not the numba this was written for: leave it alone
    # the scope copies of the call sites being inlined, innermost last, each {id(kept scope): copy}
    # (numba compiles under one lock, so no other thread copies IR meanwhile)
    sites = []
    built = {}  # (function, flags) -> the function's IR after its untyped passes, never changed

    def site_scope(scope):
        return sites[-1].get(id(scope), scope) if sites else scope

    def var_deepcopy(self, memo):
        if not sites:
            return var_copy(self, memo)
        out = ir.Var(site_scope(self.scope), self.name, self.loc)
        memo[id(self)] = out
        return out

    def scope_deepcopy(self, memo):
        if sites:
            return site_scope(self)
        return copy._reconstruct(self, memo, *self.__reduce_ex__(4))  # what deepcopy does without the method

    def scope_copy(scope):
        out = copy.copy(scope)
        out.localvars = copy.copy(scope.localvars)
        out.localvars._con = dict(scope.localvars._con)
        out.redefined = copy.copy(scope.redefined)
        out.var_redefinitions = collections.defaultdict(set, {k: set(v) for k, v in scope.var_redefinitions.items()})
        return out

    def shared_inline_function(self, caller_ir, block, i, function, arg_typs=None):
        # (typing hints of the caller could shape the callee's IR: then it is built afresh too)
        if self.locals or not _in_kernels_dir(function):
            callee_ir = self.run_untyped_passes(function)
        else:
            flags = self.flags.copy()
            flags.enable_ssa = False  # what run_untyped_passes sets
            key = (function, flags)
            callee_ir = built.get(key)
            if callee_ir is None:
                callee_ir = built[key] = self.run_untyped_passes(function)
        kept = {id(b.scope): b.scope for b in callee_ir.blocks.values()}
        sites.append({k: scope_copy(s) for k, s in kept.items()})
        try:
            return self.inline_ir(caller_ir, block, i, callee_ir, function.__code__.co_freevars, arg_typs=arg_typs)
        finally:
            sites.pop()

    shared_inline_function._spq_shared_scope = True
    ir.Var.__deepcopy__ = var_deepcopy
    ir.Scope.__deepcopy__ = scope_deepcopy
    InlineWorker.inline_function = shared_inline_function


_install_shared_scope_copies()

_HOT = "_spq_hot_kernel"


def _into_hot_kernels(expr, caller_ir, callee_ir) -> bool:
    """numba's inlining cost model for ``inline="hot"``: caller_ir is the entry point being compiled
    (the whole chain of inlined kernels ends in it)."""
    return getattr(caller_ir.func_id.func, _HOT, False)


def _one_version_per_type(dispatcher):
    """A kernel called from another with a constant argument is compiled for that constant's literal
    type (numba's default), so a kernel called with kinds 0, 1 and 2 was compiled three times over,
    each copy with every kernel it calls: here the callee sees the argument's plain type."""
    typed_for = getattr(dispatcher, "get_call_template", None)
    if typed_for is None:  # NUMBA_DISABLE_JIT: a plain function
        return dispatcher

    def get_call_template(args, kws):
        return typed_for(tuple(types.unliteral(a) for a in args),
                         {k: types.unliteral(v) for k, v in kws.items()})

    dispatcher.get_call_template = get_call_template
    return dispatcher


def kernel(fn=None, *, allocates: bool = False, hot: bool = False, **options):
    """``numba.njit`` with the project's options; use as ``@kernel``, ``@kernel(inline="always")``,
    ``@kernel(inline="hot")`` (inlined only into hot entry points), ``@kernel(hot=True)`` (an entry
    point that takes them inline) or ``@kernel(allocates=True)`` (for a kernel that creates arrays)."""
    if options.get("inline") == "hot":
        options["inline"] = _into_hot_kernels
    opts = {"cache": True, "error_model": "numpy", "_nrt": bool(allocates), **options}

    def compile_(f):
        if hot:
            setattr(f, _HOT, True)
        return _one_version_per_type(njit(**opts)(f))

    return compile_ if fn is None else compile_(fn)
