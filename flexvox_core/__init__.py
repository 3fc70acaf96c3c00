"""flexvox_core — the numerics of flexible-voxel videography.

Codes (the paper's integer program), the forward model, simulation, reconstruction,
optical flow, metrics and recording I/O. This package never imports Qt. "The paper" in flexvox's
docstrings is Gupta et al. [1]_; a module names the section or equation of it that it implements.

Reconstruction in three layers: the algorithms (:mod:`flexvox_core.reconstruct`,
:mod:`flexvox_core.motion`); the methods as objects, their registry and the one chunked runner
(:mod:`flexvox_core.methods`); and the one reader from a recording to reconstruction input
(:mod:`flexvox_core.capture_reader`), which :mod:`flexvox_core.batch`, the command line and the
application share.

Array conventions (shared by every part of flexvox):

=====================  =========================  =====================================
thing                  shape / type               notes
=====================  =========================  =====================================
high-speed video       ``(S, H, W)`` float32      S sub-frames, time first, in [0, 1]
coded capture          ``(F, H, W)``              S = F·K
code                   ``(m, n, K)`` bool         ``code[i, j, s]``: pixel open in slot s
firing order           ``(m, n)`` int             identity code as slot numbers 0..K-1
=====================  =========================  =====================================

Pixel ``(y, x)`` uses ``code[y % m, x % n]``.

References
----------
.. [1] M. Gupta, A. Agrawal, A. Veeraraghavan and S. G. Narasimhan, "Flexible Voxels for
   Motion-Aware Videography", European Conference on Computer Vision (ECCV), 2010.
"""

import lazy_loader

# The package's names, listed once in __init__.pyi (which type checkers and editors read too) and imported when first
# asked for (PEP 562, through lazy_loader): `import flexvox_core` (which every command line run does) then costs no
# scipy.optimize (the code design's solver, 0.26 s to import). `from flexvox_core import design_code` still imports
# it at once: a module that wants it only sometimes imports it where it is used. The submodules named there
# (``flexvox_core.forward``) are attributes of the package.
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
