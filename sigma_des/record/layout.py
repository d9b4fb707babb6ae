"""A Foxglove layout for a recording: the swarm framed in 3-D, its AoI plotted.

``sigma-des layout [--method M] [--out FILE]`` writes it (the package ships the one of
``bides`` as ``sigma_des/record/foxglove_layout.json``); import it in Foxglove with
*Layouts → Import from file*. It holds three panels:

* **3D**, display frame ``<method>/swarm`` (the frame that follows the swarm's centre,
  :func:`~sigma_des.record.enu.swarm_transform`) in follow mode *Position*: the camera
  stays on the swarm wherever it flies; ``/<method>/snapshot``'s poses are drawn as
  arrows long enough to see from the camera's distance, over a ground grid fixed in
  ``enu`` (so the swarm is seen moving over it);
* **Plot** of the AoI of every node, ``/<method>/render.aoi[:]`` (s; the axis starts at
  0, which hides the −1 of a node with nothing shown yet);
* **Raw Messages** of ``/<method>/tf`` (the swarm's centre, east-north-up m).

The JSON is Foxglove's layout data (``configById``, ``layout``, ``globalVariables``,
``userNodes``, ``playbackConfig``), as *Export layout* writes it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import IO, Any

from sigma_des.errors import ConfigError
from sigma_des.record.enu import FRAME_ID, swarm_frame

__all__ = ["LAYOUT_FILE", "add_layout_args", "foxglove_layout", "layout_json", "run_layout"]

#: The shipped layout (method ``bides``).
LAYOUT_FILE = Path(__file__).with_name("foxglove_layout.json")

#: Camera: distance (m) and tilt from vertical (degrees): a few dozen aircraft in view
#: while the default formation spreads to some 400 m along its route.
CAMERA_DISTANCE = 450.0
CAMERA_PHI = 40.0
#: Arrow length and shaft/head width (m): an aircraft is a few pixels long otherwise.
ARROW_SCALE = (10.0, 2.0, 4.0)
#: Ground grid in ``enu``: side and cells (m): covers the default route.
GRID_SIZE = 2000.0
GRID_DIVISIONS = 40

_3D = "3D!swarm"
_PLOT = "Plot!aoi"
_RAW = "RawMessages!tf"


def _three_d(method: str) -> dict[str, Any]:
    return {
        "cameraState": {
            "distance": CAMERA_DISTANCE, "perspective": True, "phi": CAMERA_PHI,
            "thetaOffset": 45.0, "targetOffset": [0.0, 0.0, 0.0], "target": [0.0, 0.0, 0.0],
            "targetOrientation": [0.0, 0.0, 0.0, 1.0], "fovy": 45.0, "near": 0.5,
            "far": 10000.0,
        },
        "followMode": "follow-position",
        "followTf": swarm_frame(method),
        "scene": {"transforms": {"showLabel": True, "axisScale": 10.0}},
        "transforms": {},
        "topics": {
            f"/{method}/snapshot": {"visible": True, "type": "arrow",
                                    "arrowScale": list(ARROW_SCALE), "color": "#ff6b00ff"},
        },
        "layers": {
            "ground": {
                "visible": True, "frameLocked": True, "label": "Ground (enu)",
                "instanceId": "ground", "layerId": "foxglove.Grid", "frameId": FRAME_ID,
                "size": GRID_SIZE, "divisions": GRID_DIVISIONS, "lineWidth": 1.0,
                "color": "#248eff", "position": [0.0, 0.0, 0.0], "rotation": [0.0, 0.0, 0.0],
                "order": 1,
            },
        },
    }


def foxglove_layout(method: str = "bides") -> dict[str, Any]:
    """The layout data of ``method``'s channels (see the module's description)."""
    return {
        "configById": {
            _3D: _three_d(method),
            _PLOT: {
                "title": f"AoI per node, {method} (s)",
                "paths": [{"value": f"/{method}/render.aoi[:]", "enabled": True,
                           "timestampMethod": "receiveTime"}],
                "minYValue": 0.0,  # hides the -1 of nodes with nothing shown yet
                "showLegend": True, "isSynced": True, "xAxisVal": "timestamp",
                "showXAxisLabels": True, "showYAxisLabels": True,
                "legendDisplay": "floating", "showPlotValuesInLegend": False,
                "sidebarDimension": 240,
            },
            _RAW: {"topicPath": f"/{method}/tf", "diffEnabled": False, "diffMethod": "custom",
                   "diffTopicPath": "", "showFullMessageForDiff": False},
        },
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": {
            "first": _3D,
            "second": {"first": _PLOT, "second": _RAW, "direction": "column",
                       "splitPercentage": 60},
            "direction": "row",
            "splitPercentage": 62,
        },
    }


def layout_json(method: str = "bides") -> str:
    """:func:`foxglove_layout` as the text of a layout file."""
    return json.dumps(foxglove_layout(method), indent=2) + "\n"


def add_layout_args(p: argparse.ArgumentParser) -> None:
    """``sigma-des layout``'s options."""
    p.add_argument("--method", default="bides",
                   help="the method whose channels the layout shows (default bides)")
    p.add_argument("--out", default=None, metavar="FILE.json",
                   help="write the layout here (default: print it)")


def run_layout(args: argparse.Namespace) -> int:
    """``sigma-des layout``: write or print the layout of ``--method``."""
    from sigma_des.config import ALL_METHODS

    if args.method not in ALL_METHODS:
        raise ConfigError("--method", f"unknown method {args.method!r}; allowed: "
                          f"{', '.join(ALL_METHODS)}")
    text = layout_json(args.method)
    if args.out is None:
        sys.stdout.write(text)
        return 0
    from sigma_des.guard import atomic_write, output_file

    def write(fh: IO[Any]) -> None:
        fh.write(text)

    out = output_file(args.out, "--out")
    atomic_write(out, write, "--out")
    print(f"wrote {out}: import it in Foxglove (Layouts, Import from file)")
    return 0
