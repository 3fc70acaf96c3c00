"""The options form the Review workspace and the napari plugin share: a field per option, by its kind."""

import pytest
from PySide6.QtWidgets import QCheckBox, QComboBox, QDoubleSpinBox, QLineEdit, QSpinBox

from flexvox_app.gui.widgets.options_form import OptionsForm
from flexvox_core.divisions import Division
from flexvox_core.methods import Method, get


def test_each_option_gets_its_kind_s_field_and_the_form_gives_the_method_s_defaults(qtbot):
    kinds = {"check": QCheckBox, "list": QComboBox, "whole": QSpinBox, "real": QDoubleSpinBox, "text": QLineEdit}
    for name in ("rebin", "diffusion", "gap-tv", "motion-aware"):
        form = OptionsForm(get(name))
        qtbot.addWidget(form)
        for o in get(name).option_specs:
            assert type(form.widgets[o.name]) is kinds[o.kind.field], (name, o.name)
        assert Method(name, **form.values((2, 4))) == Method(name), name


def test_values_shown_are_the_values_read(qtbot):
    form = OptionsForm(get("diffusion"))
    qtbot.addWidget(form)
    form.set_value("tensor", (0.2, 0.3, 1.0))
    form.set_value("time", 2.5)
    form.set_value("solver", "explicit")
    assert form.widgets["tensor"].text() == "0.2,0.3,1"
    assert form.values() == {"tensor": (0.2, 0.3, 1.0), "time": 2.5, "solver": "explicit"}
    rebin = OptionsForm(get("rebin"))
    qtbot.addWidget(rebin)
    rebin.set_value("block", "2x1x4")
    assert rebin.values((2, 4))["block"] == Division(2, 1, 4)
    rebin.set_value("block", None)
    assert rebin.widgets["block"].text() == "" and rebin.values((2, 4))["block"] is None


def test_text_a_field_cannot_read_is_refused_naming_the_option(qtbot):
    form = OptionsForm(get("rebin"))
    qtbot.addWidget(form)
    form.set_value("block", "3x1x1")
    with pytest.raises(ValueError, match=r"division 3x1x1 does not divide a 2x4 tile"):
        form.values((2, 4))
    form.set_value("block", "two")
    with pytest.raises(ValueError, match=r"`block` must be three whole numbers a,b,c .*; got 'two'"):
        form.values((2, 4))


def test_a_default_of_none_is_a_value_of_its_own(qtbot):
    form = OptionsForm(get("motion-aware"))
    qtbot.addWidget(form)
    reach, refine = form.widgets["slow_reach"], form.widgets["refine_time"]
    assert reach.value() == 0.75 and form.values()["slow_reach"] is None  # the number the pipeline uses
    reach.setValue(2.0)
    assert form.values()["slow_reach"] == 2.0
    assert refine.text() == "default ((K/16)²)" and form.values()["refine_time"] is None
    refine.setValue(1.0)
    assert form.values()["refine_time"] == 1.0


def test_kept_values_come_back_and_skipped_options_have_no_field(qtbot, settings):
    form = OptionsForm(get("gap-tv"), settings=settings, key="here/gap-tv")
    qtbot.addWidget(form)
    seen = []
    form.changed.connect(lambda: seen.append(True))
    form.widgets["iterations"].setValue(77)
    assert seen
    form.save()
    again = OptionsForm(get("gap-tv"), settings=settings, key="here/gap-tv", skip=("tv_weight",))
    qtbot.addWidget(again)
    assert again.widgets["iterations"].value() == 77 and list(again.widgets) == ["iterations", "tv_iterations"]
