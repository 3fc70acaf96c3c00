"""The estimate's inputs a notebook user gets wrong: refused in words, never read as something else."""

import numpy as np
import pytest

from flexvox_core import Method, capture, estimate_accuracy, render_scene
from flexvox_core.accuracy import NoiseModel, NotEstimable
from flexvox_core.design import design_code


def test_a_misspelt_effect_is_refused_not_read_as_no_noise():
    with pytest.raises(ValueError, match=r"`effects` names 'read_nois', which the simulator does not have .*a "
                                         r"misspelt noise would be read as none"):
        NoiseModel.from_effects({"read_nois": {}})
    assert NoiseModel.from_effects({"read_noise": {}}).floor > 0  # the right name still reads


@pytest.mark.parametrize(("effects", "kw", "match"), [
    # a misspelt parameter had been read as its default (sigma 3), a negative sigma as its opposite, a NaN as a NaN
    # floor, a gain of 0 raised ZeroDivisionError, electrons_per_unit=0 was read as not stated (1000)
    ({"read_noise": {"sigm": 20.0}}, {}, r"effect 'read_noise' has no parameter 'sigm'; its parameters: sigma"),
    ({"read_noise": {"sigma": -1}}, {}, r"read_noise.sigma must be between 0 and 10000 e- rms; got -1"),
    ({"read_noise": {"sigma": float("nan")}}, {}, r"read_noise.sigma must be between 0 and 10000 .*got nan"),
    ({"adc": {"gain": 0}}, {}, r"adc.gain must be between 1e-06 and 1000 DN/e-; got 0"),
    ({"photon_noise": {}}, {"electrons_per_unit": 0}, r"`electrons_per_unit` must be a positive finite number of "
                                                      r"electrons; got 0"),
    ({"dark_current": {}, "photon_noise": {}}, {"rate_hz": -15}, r"`rate_hz` must be a positive finite number"),
])
def test_effects_parameters_follow_the_simulator_s_rules(effects, kw, match):
    with pytest.raises(ValueError, match=match):
        NoiseModel.from_effects(effects, **kw)


@pytest.mark.parametrize("given", [{"photon": -1.0}, {"floor": float("nan")}, {"photon": "0.001"}])
def test_a_noise_model_holds_variances(given):
    # NoiseModel(photon=-1) was estimated with: 6.5 dB for a run of 20 dB
    with pytest.raises(ValueError, match=r"`(photon|floor)` must be a finite number >= 0 \(a variance in relative "
                                         r"units\); got"):
        NoiseModel(**given)
    assert NoiseModel(np.float32(0.001), 0).photon == pytest.approx(0.001)


@pytest.mark.parametrize("effects", [["photon_noise", "read_noise"], {"read_noise": 3.0}])
def test_effects_that_are_not_a_dict_of_parameters_are_refused(effects):
    with pytest.raises(TypeError, match=r"`effects` must be a dict of \{effect name: \{parameter: value\}\}"):
        NoiseModel.from_effects(effects)


def test_noise_given_by_name_is_refused_naming_the_noise_model():
    code = design_code((2, 2)).code
    frames = capture(render_scene("balls", 8, 24, 32), code)
    with pytest.raises(TypeError, match=r"`noise` must be a NoiseModel .*got 'read_noise'"):
        estimate_accuracy(frames, code, Method("diffusion"), noise="read_noise")


def test_an_exact_reconstruction_without_stated_noise_says_so():
    code = design_code((2, 2)).code
    frames = np.full((4, 24, 32), 0.4, np.float32)  # a capture without change: every sample predicted exactly
    with pytest.raises(NotEstimable, match=r"predicted exactly .*no noise is stated"):
        estimate_accuracy(frames, code, Method("diffusion"))


def test_a_crop_off_the_tile_grid_is_estimated_at_its_origin_s_phase():
    from flexvox_core.methods.runner import code_at_origin

    code = design_code((2, 4)).code
    whole = capture(render_scene("balls", 4 * 8, 30, 40), code)
    crop = whole[:, 5:29, 7:39]  # 24x32 from (5, 7): off the 2x4 grid both ways
    at = estimate_accuracy(crop, code, Method("diffusion"), origin=(5, 7))
    rolled = estimate_accuracy(crop, code_at_origin(code, (5, 7)), Method("diffusion"))
    assert at.psnr == rolled.psnr and at.low == rolled.low  # the code's phase follows the origin
    # Without the origin the crop is read at the wrong phase, which the estimate cannot see (it measures the
    # reconstruction's consistency with the samples as assigned): a different figure, not a warning.
    assert estimate_accuracy(crop, code, Method("diffusion")).psnr != at.psnr
    with pytest.raises(ValueError, match=r"`origin` must be two whole numbers >= 0"):
        estimate_accuracy(crop, code, Method("diffusion"), origin=(-1, 0))
