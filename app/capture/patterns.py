"""A code tiled over the camera, turned into the projector's K patterns.

This is the capture service's own, deliberately small, stand-in for the calibration
package's shutter masks (``calibration.shutter.make_shutter_patterns``): same convention,
no dependency, so capture works before calibration does and can swap to it later by
passing ``pattern_maker=`` to :class:`~app.capture.service.CaptureService`.

Convention
----------
Camera pixel ``(y, x)`` opens in the slots of ``code[y % m, x % n]`` (DESIGN §2). Each
projector pixel takes the slots of the camera pixel *nearest* to where the projector→camera
homography sends its centre: OpenCV's ``warpPerspective`` with ``WARP_INVERSE_MAP`` and
nearest interpolation, i.e. the destination (projector) grid sampled through the
homography into the source (camera) grid. Projector pixels that land outside the camera
stay dark. Then the sync phase is compensated: with phase ``p`` (exposure slot ``t`` sees
projector pattern ``(t + p) mod K``), pattern ``j`` carries code slot ``(j − p) mod K``, so
exposure slot ``s`` sees code slot ``s``.

Where projector pixels are larger than camera pixels some camera pixels get no mirror of
their own and see a neighbour's slot; the calibration package reports that, this does not.
"""

from __future__ import annotations

import cv2
import numpy as np

from flexvox_core.codes import validate_code
from flexvox_core.forward import tiled_code
from rig_drivers.simulated_rig import check_homography  # noqa: F401 - re-exported for the service


def shutter_patterns(code, camera_size, projector_size, *, homography=None, phase_slots: int = 0) -> np.ndarray:
    """The projector patterns ``(K, Hp, Wp)`` bool that shutter each camera pixel by ``code``.

    Parameters
    ----------
    code : ndarray, shape (m, n, K), bool
    camera_size, projector_size : (H, W)
    homography : array (3, 3), optional
        Projector pixel (x, y) → camera pixel (x, y). Default identity.
    phase_slots : int
        Sync phase, ``0 <= phase_slots < K``.

    Examples
    --------
    >>> from flexvox_core.design import design_code
    >>> p = shutter_patterns(design_code((2, 2)).code, (4, 6), (4, 6))
    >>> p.shape, bool((p.sum(axis=0) == 1).all())
    ((4, 4, 6), True)
    """
    c = validate_code(code)
    K = c.shape[2]
    if isinstance(phase_slots, bool) or not isinstance(phase_slots, int | np.integer) or not 0 <= phase_slots < K:
        raise ValueError(f"`phase_slots` must be a whole number 0..{K - 1}; got {phase_slots!r}")
    H, W = (int(v) for v in camera_size)
    Hp, Wp = (int(v) for v in projector_size)
    h = np.eye(3) if homography is None else check_homography(homography)
    cam = tiled_code(c, H, W).astype(np.uint8)  # (K, H, W)
    if np.array_equal(h, np.eye(3)) and (H, W) == (Hp, Wp):
        pats = cam.astype(bool)
    else:
        pats = np.empty((K, Hp, Wp), bool)
        for k in range(K):
            pats[k] = cv2.warpPerspective(cam[k], h, (Wp, Hp), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                                          borderMode=cv2.BORDER_CONSTANT, borderValue=0) > 0
    return np.roll(pats, int(phase_slots), axis=0)
