"""Draw docs/figures/session/pivots.png: the rigid bodies' pivots, the EUC's points and the body axes.

    python docs/figures/session/pivots.py

Side view (x forward, z up) of a rider standing on an EUC, with segment heights from
euc_ros.core.anthropometry (a 1.75 m male) and the EUC paper's geometry (R = 0.2 m, l0, h0).
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from euc_ros.core.anthropometry import SHOULDER_BELOW_C7, STATURE_M, ankle_height, segment_lengths  # noqa: E402

H, R, L0, H0 = 1.75, 0.2, 0.05, 0.075
L = segment_lengths(H, "male")
k = H / STATURE_M["male"]
axle = R
ankle = axle + L0                          # the ankle hinge A stands l0 above the wheel centre C
lift = ankle - ankle_height(L, H)          # the standing body raised onto the pedals
knee, hip = ankle + L["shank"], ankle + L["shank"] + L["thigh"]
c7 = hip + L["trunk"]
shoulder = c7 - SHOULDER_BELOW_C7 * k
elbow, wrist = shoulder - L["upper_arm"], shoulder - L["upper_arm"] - L["forearm"]
top = H + lift
pivots = {"H (top of helmet)": (0.0, top), "CHR/CHL (shoulder)": (0.0, shoulder), "UAR/UAL (elbow)": (0.03, elbow),
          "LAR/LAL (wrist)": (0.06, wrist), "HR/HL (hip)": (0.0, hip), "TR/TL (knee)": (0.02, knee),
          "LR/LL (ankle) = hinge A": (0.0, ankle)}
fig, ax = plt.subplots(figsize=(6.2, 7.5))
ax.add_patch(plt.Circle((0, axle), R, fill=False, lw=2, color="0.3"))
ax.plot([-0.04, 0.04, 0.04, -0.04, -0.04], [axle - 0.02, axle - 0.02, axle + 0.42, axle + 0.42, axle - 0.02],
        color="0.3", lw=1.5)
ax.plot([0, 0.02, 0.0, 0.03, 0.06, 0.03, 0.0, 0.0, 0.0], [ankle, knee, hip, elbow, wrist, elbow, shoulder, c7, top],
        color="tab:blue", lw=1, alpha=0.5)
for name, (x, z) in pivots.items():
    ax.plot(x, z, "o", color="tab:blue", ms=6)
    ax.annotate(name, (x, z), xytext=(0.12, z - (0.06 if "wrist" in name else 0.0)), textcoords="data",
                va="center", fontsize=9,
                arrowprops={"arrowstyle": "-", "color": "0.6", "lw": 0.6})
ax.plot(0, axle, "k+", ms=12)
ax.annotate("C: wheel centre", (0, axle), xytext=(-0.55, axle - 0.05), fontsize=9,
            arrowprops={"arrowstyle": "-", "color": "0.6", "lw": 0.6})
ax.plot(0, axle + H0, "s", color="tab:green", ms=6)
ax.annotate("G0: EUC body's CoG (h0 above C)", (0, axle + H0), xytext=(-0.75, axle + 0.2), fontsize=9,
            arrowprops={"arrowstyle": "-", "color": "0.6", "lw": 0.6})
ax.plot(0, axle + 0.42, "D", color="tab:red", ms=6)
ax.annotate("E: EUC body's pivot (top)\npivot_to_wheel_center = C - E\nin E's frame", (0, axle + 0.42),
            xytext=(-0.75, axle + 0.55), fontsize=9, arrowprops={"arrowstyle": "-", "color": "0.6", "lw": 0.6})
ax.annotate("", (0.70, 0.45), (0.50, 0.45), arrowprops={"arrowstyle": "->", "lw": 1.2})
ax.annotate("", (0.50, 0.65), (0.50, 0.45), arrowprops={"arrowstyle": "->", "lw": 1.2})
ax.text(0.62, 0.40, "x forward", va="top", ha="center", fontsize=9)
ax.text(0.50, 0.67, "z up", ha="center", fontsize=9)
ax.text(0.40, 0.33, "body frames: x forward, y left,\nz up when the rider stands upright", fontsize=8, color="0.3")
ax.axhline(0, color="k", lw=1)
ax.set_xlim(-0.8, 0.9)
ax.set_ylim(-0.05, top + 0.1)
ax.set_aspect("equal")
ax.set_xlabel("x [m]")
ax.set_ylabel("z [m]")
ax.set_title("Pivots of the rigid bodies (side view)", fontsize=10)
fig.set_layout_engine("constrained")
out = Path(__file__).with_suffix(".png")
fig.savefig(out, dpi=130)
print(out)
