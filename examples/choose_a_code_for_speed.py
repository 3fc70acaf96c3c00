"""Which code should I use for my scene's speed?

A larger tile samples more instants per camera frame (K = m·n) at the cost of spatial detail. This
simulates one scene moving slowly and quickly, captures it with 2×2, 3×3 and 4×4 codes at the same
sub-frame rate, reconstructs each with motion-aware, and prints the PSNR of each pair.

    python examples/choose_a_code_for_speed.py [SCENE]
"""

import sys

from _sample import FRAMES, SIZE

import flexvox_core as fv

scene = sys.argv[1] if len(sys.argv) > 1 else "balls"
tiles = [(2, 2), (3, 3), (4, 4)]
S = FRAMES * 16                                  # sub-frames: the same clip for every tile
print(f"{scene}, {S} sub-frames of {SIZE[0]}x{SIZE[1]}")
for speed, every in (("slow", 1), ("fast", 2)):
    # "fast": every other sub-frame of a clip twice as long, so the scene moves twice as far per sub-frame
    clip = fv.render_scene(scene, S * every, *SIZE, seed=0)[::every]
    row = []
    for tile in tiles:
        code = fv.design_code(tile).code
        K = code.shape[2]
        truth = clip[: (S // K) * K]
        sim = fv.simulate_video(truth, code, seed=1, effects={"read_noise": {"sigma": 1.0}})
        row.append(f"{tile[0]}x{tile[1]}: {fv.psnr(truth, fv.reconstruct_video(sim.normalised(), code)):5.2f} dB")
    print(f"  {speed}: " + "   ".join(row))
