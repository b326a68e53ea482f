"""Virtual-leader reference of docs/scenario.md: paper trajectory and analytic derivatives."""
import math

import numpy as np
import pytest

from uh_core.records import Reference
from uh_core.reference import ReferenceParameterError, VirtualLeaderReference
from uh_topology.scenario import load_scenario

PAPER = VirtualLeaderReference(load_scenario('paper').reference)
OTHER = VirtualLeaderReference({'radius': 4.0, 'angular_rate': -0.35, 'center': [1.0, -2.0, 5.0],
                                'climb_rate': -0.2, 'yaw_rate': 0.25, 'initial_yaw': 1.0})
TIMES = [0.0, 0.37, 5.0, 13.3, 31.4, 59.99]


@pytest.mark.parametrize('t', TIMES)
def test_paper_trajectory_is_the_one_of_design_2_7(t):
    ref = PAPER.at(t)
    assert isinstance(ref, Reference)
    np.testing.assert_allclose(ref.position, [10 * math.sin(0.1 * t), 10 - 10 * math.cos(0.1 * t),
                                              10 + 0.1 * t], rtol=0, atol=1e-13)
    assert ref.yaw == pytest.approx(0.1 * t, abs=1e-15)
    assert ref.yaw_rate == 0.1
    np.testing.assert_array_equal(PAPER.position(t), ref.position)


@pytest.mark.parametrize('reference', [PAPER, OTHER], ids=['paper', 'other'])
@pytest.mark.parametrize('t', TIMES)
def test_derivatives_match_central_differences(reference, t):
    h = 1e-4
    before, after = reference.at(t - h), reference.at(t + h)
    ref = reference.at(t)
    # central differences: truncation h^2/6 |p'''| <= 1e-8 * r w^3 ~ 1e-10, rounding
    # eps |p| / h ~ 2e-16 * 20 / 1e-4 ~ 5e-11: 1e-8 is a safe bound that still catches a wrong factor
    np.testing.assert_allclose(ref.velocity, (after.position - before.position) / (2 * h), atol=1e-8)
    np.testing.assert_allclose(ref.acceleration, (after.velocity - before.velocity) / (2 * h), atol=1e-8)
    assert ref.yaw_rate == pytest.approx((after.yaw - before.yaw) / (2 * h), abs=1e-8)


def test_other_parameters_are_used():
    ref = OTHER.at(2.0)
    wt = -0.35 * 2.0
    np.testing.assert_allclose(ref.position, [1 + 4 * math.sin(wt), -2 - 4 * math.cos(wt), 5 - 0.4], atol=1e-14)
    assert ref.yaw == pytest.approx(1.5, abs=1e-15)
    np.testing.assert_array_equal(OTHER.center, [1.0, -2.0, 5.0])


@pytest.mark.parametrize('spec, message', [
    ({'radius': 1.0}, r"lack 'angular_rate'"),
    ({'radius': -1.0, 'angular_rate': 0.1, 'center': [0, 0, 0], 'climb_rate': 0, 'yaw_rate': 0,
      'initial_yaw': 0}, r'radius must be >= 0 m, got -1.0'),
    ({'radius': 1.0, 'angular_rate': 0.1, 'center': [0, 0], 'climb_rate': 0, 'yaw_rate': 0,
      'initial_yaw': 0}, r'center must have 3 components'),
    ({'radius': 1.0, 'angular_rate': float('nan'), 'center': [0, 0, 0], 'climb_rate': 0, 'yaw_rate': 0,
      'initial_yaw': 0}, r'must be finite'),
    ({'radius': 'big', 'angular_rate': 0.1, 'center': [0, 0, 0], 'climb_rate': 0, 'yaw_rate': 0,
      'initial_yaw': 0}, r'must be numbers'),
])
def test_invalid_parameters_raise(spec, message):
    with pytest.raises(ReferenceParameterError, match=message):
        VirtualLeaderReference(spec)
