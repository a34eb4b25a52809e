"""The contact depth MuJoCo reports for a 2 cm box overlapping a box and a plane by 1 mm.

Upstream kindergarden 0.2.5 runs on MuJoCo 3.3.7; this project ran on MuJoCo 4.0.0 before it
pinned upstream's version (any 4.x interpreter shows the other side). Their box-box
colliders differ: for a box whose face overlaps another box's face by 1 mm, 3.3.7 reports a
contact distance of -0.5 mm, 4.0.0 of -1 mm (box-plane contacts report -1 mm on both). The
constraint's spring acts on the reported depth, so in 3.3.7 every box-box contact (a block on a
table top, on another block, against a bin wall) is about half as stiff against the real overlap:
resting blocks sink about 0.1 mm deeper and dropped blocks bounce less. This is what makes
SortClutteredBlocks3D-o20's pile of twenty dropped blocks spread less, stack more, and knock a bin
less often in upstream's resets than in ours did on 4.0.0 (``tools/conformance/table.py``).

Run it with interpreters that have each version to compare them (``uv run --with mujoco==4.0.0``
gives one with 4.0.0):

    .venv/bin/python benchmarks/probes/box_contact_depth.py
    uv run --no-project --with mujoco==4.0.0 python benchmarks/probes/box_contact_depth.py
"""

from __future__ import annotations

import mujoco
import numpy as np

#: A 2 cm box resting 1 mm into the 4 cm table top (box-box) or into a plane at the same height.
SUPPORTS = {
    "box": '<geom type="box" size="0.3 0.6 0.02" pos="0 0 0.38"/>',
    "plane": '<geom type="plane" size="1 1 0.1" pos="0 0 0.4"/>',
}
OVERLAP = 1e-3


def reported_depths(support: str) -> list[float]:
    """The distinct contact distances (m) between the box and ``support`` at ``OVERLAP``."""
    xml = f"""<mujoco><worldbody>{SUPPORTS[support]}
      <body pos="0 0 {0.41 - OVERLAP}"><freejoint/><geom type="box" size="0.01 0.01 0.01"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return sorted({round(float(d), 6) for d in np.asarray(data.contact.dist[: data.ncon])})


def main() -> None:
    for support in SUPPORTS:
        print(
            f"MuJoCo {mujoco.__version__}: a 2 cm box {OVERLAP * 1e3:g} mm into a {support}: "
            f"reported contact distance {reported_depths(support)} m"
        )


if __name__ == "__main__":
    main()
