#!/usr/bin/env python3
"""Chart the validity map: L1 distance of the in-plane distribution against the Kirchhoff
orders, for rays and the diffraction method, against period / wavelength (log axis).

Reads the Markdown table printed by
    cargo test --release --test diffraction validity_map -- --ignored --nocapture
on standard input and writes an SVG (no dependencies beyond Python 3).

    cargo test ... | python3 scripts/validity-chart.py docs/validity-map.svg
"""
import math
import sys

rows = []
for line in sys.stdin:
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    if len(cells) != 5 or not cells[0][0].isdigit():
        continue
    ratio, theta = float(cells[0]), float(cells[1])
    rays_l1 = float(cells[3].split(",")[1])
    diff_l1 = float(cells[4].split(",")[1])
    rows.append((ratio, theta, rays_l1, diff_l1))
if not rows:
    sys.exit("no table rows on standard input")

W, H, L, R, T, B = 640, 400, 70, 20, 30, 60
x0, x1 = math.log10(1.5), math.log10(50.0)


def sx(v):
    return L + (math.log10(v) - x0) / (x1 - x0) * (W - L - R)


def sy(v):
    return T + (1.0 - v / 2.0) * (H - T - B)


out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">',
       f'<rect width="{W}" height="{H}" fill="white"/>']
for v in [0.0, 0.5, 1.0, 1.5, 2.0]:
    out.append(f'<line x1="{L}" x2="{W - R}" y1="{sy(v):.1f}" y2="{sy(v):.1f}" stroke="#ddd"/>')
    out.append(f'<text x="{L - 8}" y="{sy(v) + 4:.1f}" text-anchor="end">{v:.1f}</text>')
for v in [2, 3, 5, 10, 20, 50]:
    out.append(f'<line y1="{T}" y2="{H - B}" x1="{sx(v):.1f}" x2="{sx(v):.1f}" stroke="#ddd"/>')
    out.append(f'<text y="{H - B + 18}" x="{sx(v):.1f}" text-anchor="middle">{v}</text>')
# The validity thresholds: below 3 wavelengths nothing here holds.
out.append(f'<rect x="{L}" y="{T}" width="{sx(3) - L:.1f}" height="{H - T - B}" fill="#f4cccc" opacity="0.5"/>')
out.append(f'<text x="{L + 4}" y="{T + 14}" fill="#900">rigorous only</text>')
out.append(f'<text x="{(L + W - R) / 2}" y="{H - 18}" text-anchor="middle">period / wavelength (sinusoidal glass grating, A / period = 0.05, 550 nm)</text>')
out.append(f'<text transform="translate(18,{(T + H - B) / 2}) rotate(-90)" text-anchor="middle">L1 against Kirchhoff orders (2 deg bins; 2 = disjoint)</text>')
series = [("rays, 0 deg", 2, 0.0, "#1f77b4", ""), ("rays, 30 deg", 2, 30.0, "#1f77b4", "4,3"),
          ("diffraction, 0 deg", 3, 0.0, "#d62728", ""), ("diffraction, 30 deg", 3, 30.0, "#d62728", "4,3")]
for i, (name, col, theta, colour, dash) in enumerate(series):
    pts = [(r[0], r[col]) for r in rows if r[1] == theta]
    path = " ".join(f"{sx(a):.1f},{sy(b):.1f}" for a, b in pts)
    out.append(f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="2" stroke-dasharray="{dash}"/>')
    for a, b in pts:
        out.append(f'<circle cx="{sx(a):.1f}" cy="{sy(b):.1f}" r="3" fill="{colour}"/>')
    ly = T + 40 + 16 * i
    out.append(f'<line x1="{W - 200}" x2="{W - 175}" y1="{ly}" y2="{ly}" stroke="{colour}" stroke-width="2" stroke-dasharray="{dash}"/>')
    out.append(f'<text x="{W - 170}" y="{ly + 4}">{name}</text>')
out.append("</svg>")
tmp = sys.argv[1] + ".tmp"
with open(tmp, "w") as f:
    f.write("\n".join(out) + "\n")
    f.flush()
    import os
    os.fsync(f.fileno())
os.replace(tmp, sys.argv[1])
