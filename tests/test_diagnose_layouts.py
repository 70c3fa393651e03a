"""diagnose names hidden effects with their location on rigs other than the chain.

Records from tests/hidden_layouts.py (independent reference simulators on a rig assembled
by hand, noise, quantisation; sizes and locations drawn from the seed and never passed to
the package).  One seed per case here; benchmarks/detection_layouts.py runs 20 seeds per
case (pairs included) and 50 null records per layout.
"""

import dataclasses

import numpy as np
import pytest
from hidden_layouts import layout_rig, make_layout_case
from hidden_pairs import judge

from bayesmodal import ConfigError
from bayesmodal.discrepancy.diagnosis import DEFAULT_CANDIDATES, diagnose
from bayesmodal.model.system import Drive

#: (layout, case, seed)
CASES = [("two_frame_at_drive", "none", 1), ("two_frame_at_drive", "coulomb_friction", 1),
         ("two_frame_at_drive", "end_stop", 1), ("two_frame_at_drive", "cubic_stiffness", 1),
         ("one_cart", "coulomb_friction", 2), ("one_cart", "drive_deadband", 1)]
CANDIDATES = tuple(DEFAULT_CANDIDATES) + ("end_stop",)


@pytest.mark.slow
@pytest.mark.parametrize(("layout", "case", "seed"), CASES)
def test_names_the_hidden_effects_and_where(layout, case, seed):
    h = make_layout_case(layout, case, seed)
    d = diagnose(h.experiment, rig=layout_rig(layout), posterior=False, n_null=19, rng=seed,
                 candidates=CANDIDATES)
    ok, found = judge(h, d)
    assert ok, f"truth {h.effects} {h.sizes}; found {found}; notes {d.notes}"
    if case == "none":
        return
    msg = f"{h.sizes}, {d.gain}"
    after = np.array(d.gain["fit_percent_after"])
    before = np.array(d.gain["fit_percent_before"])
    assert np.all(after >= before), msg


def test_unsupported_candidates_are_refused_or_left_out():
    """On a rig whose motor drives two carts, backlash cannot act: asked for by name it is
    refused with the fix; the default catalogue leaves it out with a note."""
    h = make_layout_case("two_frame_at_drive", "none", 1, n_samples=400)
    rig = dataclasses.replace(layout_rig("two_frame_at_drive"),
                              drive=(Drive("1"), Drive("2", 0.25)))
    with pytest.raises(ConfigError, match="exactly one cart"):
        diagnose(h.experiment, rig=rig, candidates=["backlash"], posterior=False, n_null=19)


@pytest.mark.slow
def test_a_pair_no_single_effect_explains_is_found_from_the_most_significant_one():
    """One cart, friction with a drive dead band (the layouts benchmark's seed 20007, where
    ``none`` was returned): friction alone and the dead band alone each leave the residual
    statistic higher than the linear model's, so no single effect passes; forward
    selection from the most significant one finds both, with the friction on cart 1.
    Negative control: a record of the same rig that hides nothing ends with ``none``."""
    h = make_layout_case("one_cart", "coulomb_friction+drive_deadband", 20007)
    kw = dict(rig=layout_rig("one_cart"), posterior=False, n_null=19, rng=20007,
              candidates=CANDIDATES)
    d = diagnose(h.experiment, **kw)
    ok, found = judge(h, d)
    assert ok, f"truth {h.effects} {h.sizes}; found {found}; notes {d.notes}"
    assert any(n.startswith("no single effect passes") for n in d.notes), d.notes
    null = diagnose(make_layout_case("one_cart", "none", 20007).experiment, **kw)
    assert null.cause == "none", null.notes


@pytest.mark.slow
def test_a_slow_drive_tells_friction_with_an_offset_from_directional_friction():
    """One cart, friction with a drive offset (the layouts benchmark's seed 20002): under
    pulses and steps alone the cart moves as under directional friction and the diagnosis
    names that, with a note advising a slow drive (negative control); the same record
    followed by a slow triangle of the drive names friction on cart 1 and the offset,
    with a note that the records chose the reading."""
    kw = dict(rig=layout_rig("one_cart"), posterior=False, n_null=19, rng=20002,
              candidates=CANDIDATES)
    plain = diagnose(make_layout_case("one_cart", "coulomb_friction+input_offset",
                                      20002).experiment, **kw)
    assert plain.cause == "coulomb_directional", plain.notes
    assert any("add a slow ramp" in n for n in plain.notes), plain.notes
    h = make_layout_case("one_cart", "coulomb_friction+input_offset", 20002, slow_drive=True)
    d = diagnose(h.experiment, **kw)
    ok, found = judge(h, d)
    assert ok, f"truth {h.effects} {h.sizes}; found {found}; notes {d.notes}"
    assert any("records chose" in n for n in d.notes), d.notes
