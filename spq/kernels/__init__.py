"""spq's compiled kernels (numba, over flat arrays; spq.kernels.jit has the decorator and its rules).

A kernel's arguments travel in a few tuples, each unpacked at the top of the kernel that takes it,
so that no signature runs past a dozen names (numba passes a tuple's members as it would the loose
arguments: the machine code and the results are the same):

- ``pair``: ``(kA, mA, fA, iA, kB, mB, fB, iB, R, t)``, two shapes and B's pose in A's frame. A
  shape is its kind (spq.kernels.kinds), its margin (m), and its packed floats and int32s (see
  ``Shape.kernel_data``); R (3, 3) and t (3,) map B's frame into A's.
- ``tol``: ``(tol_abs, tol_rel, max_iter)``, the stopping rule (m, m/m, iterations).
- ``scratch``: ``(R, t, work, iwork)`` from :func:`spq.kernels.batch.query_scratch`, a thread's own.
- the per-call entry point, where each argument costs time to unbox, takes a Pair's ``state``
  (:func:`spq.kernels.batch.pair_state`), each shape's ``packed`` array (its fdata and idata in one,
  spq.kernels.kinds.pack_shape) and a thread's ``wbuf`` (:func:`spq.kernels.batch.query_work`).
- a robot scene's ``chain`` (the kinematic tree), ``slots`` (its bodies) and ``pairs`` (their
  queries), as :func:`spq.kernels.scene.scene_distances` describes them.
- a 3-vector that a kernel takes as a whole (a normal ``n``, a centre ``c``) is a tuple of floats.
"""
