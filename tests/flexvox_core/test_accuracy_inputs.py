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
