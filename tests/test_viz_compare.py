"""`rhi view --compare`: the RHI and its locked NHI side by side in one page under the same hand."""

from __future__ import annotations

import numpy as np
import pytest

import rhi
from rhi.errors import InvalidInput
from rhi.sim.hand import DraggableHand

pytest.importorskip("viser")


def test_following_hand_moves_by_the_leaders_displacement_from_its_own_start():
    from rhi.viz.compare import FollowingHand

    lead = DraggableHand(stiffness=200.0, damping=5.0, max_force=12.0)
    follow = FollowingHand(lead, [0.5, 0.3], [0.5, -0.2])
    assert follow.target is None and np.all(follow.force(0.0, np.zeros(2), np.zeros(2)) == 0.0)
    lead.target = [0.52, 0.35]
    np.testing.assert_allclose(follow.target, [0.52, -0.15], atol=1e-15)
    # the leader's hand law: the same stiffness, damping and saturation
    np.testing.assert_allclose(follow.force(0.0, np.array([0.5, -0.2]), np.zeros(2)), [4.0, 10.0], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(follow.force(0.0, np.array([0.5, -0.5]), np.zeros(2))), 12.0)
    lead.target = None
    assert follow.target is None
    with pytest.raises(InvalidInput, match="target"):
        follow.target = [0.0, 0.0]
    with pytest.raises(InvalidInput, match="x_self"):
        FollowingHand(lead, [0.0, 0.0], [np.nan, 0.0])


def test_devices_are_placed_side_by_side_without_overlap():
    from rhi.viz.compare import side_by_side
    from rhi.viz.posed import Posed, rest_configuration

    devs = [rhi.device("rhi4"), rhi.device("phantom")]
    q0s = [rest_configuration(d) for d in devs]
    offsets = side_by_side(devs, q0s)
    assert np.all(offsets[0] == 0.0) and offsets[1][0] > 0.0 and np.all(offsets[1][1:] == 0.0)
    boxes = []
    for d, q, off in zip(devs, q0s, offsets):
        p = Posed(d)
        p.set(q)
        lo, hi = p.bounds()
        boxes.append((lo + off, hi + off))
    assert boxes[1][0][0] > boxes[0][1][0]  # the second device starts right of the first one's box
