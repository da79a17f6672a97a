"""How the capture modules compile with numba.

A *kernel* is called from Python and kept in numba's on-disk cache (``cache=True``): a later process loads it
in milliseconds instead of compiling it for seconds. An *inner* function is called only from other compiled
functions; its code is compiled into each caller's cached library, so it needs no cache entry of its own.
That matters when kernels are compiled by several processes at once (:mod:`facepuppet.capture.color.precompile`):
numba names a function's cache files by a counter read from its index, so two processes writing entries of
the same function for different argument types can take the same file. Kernels are compiled for one set of
argument types each, and inner functions write nothing, so parallel compiles never meet.
"""

#: Options of a kernel called from Python.
KERNEL = {"cache": True, "nogil": True, "error_model": "numpy"}
#: Options of a function called only from compiled code.
INNER = {"nogil": True, "error_model": "numpy"}
