#!/usr/bin/env python3
"""Writes meshes/afm-gold-scan.x3p: a measured-like AFM scan of a gold film, as an
ISO 25178-72 X3P container (main.xml + bindata/data.bin, float64 metres, x fastest).

The surface is synthetic, so its heights are known: 96 x 96 points 250 nm apart (a 24 um
scan), grains as Gaussian bumps of 20-60 nm at random places (seeded), a residual tilt of
1 nm/um that levelling left, and 12 drop-outs (NaN), as AFM scans have where the tip lost
the surface. Standard library only; the output is the same bytes on every run.

    python3 scripts/make-measured-sample.py
"""
import math
import random
import struct
import zipfile
from pathlib import Path

NX = NY = 96
DX = 250e-9  # m
rng = random.Random(20261130)
grains = [(rng.uniform(0, NX * DX), rng.uniform(0, NY * DX), rng.uniform(20e-9, 60e-9),
           rng.uniform(0.6e-6, 1.6e-6)) for _ in range(140)]


def height(x, y):
    z = 1e-3 * (x + 0.5 * y)  # 1 nm per um residual tilt
    for gx, gy, h, w in grains:
        z += h * math.exp(-((x - gx) ** 2 + (y - gy) ** 2) / (2 * w * w))
    return z


z = [height(i * DX, j * DX) for j in range(NY) for i in range(NX)]
for _ in range(12):
    z[rng.randrange(NX * NY)] = float("nan")
data = b"".join(struct.pack("<d", v) for v in z)

xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2">
  <Record1>
    <Revision>ISO5436 - 2000</Revision>
    <FeatureType>SUR</FeatureType>
    <Axes>
      <CX><AxisType>I</AxisType><DataType>D</DataType><Increment>{DX:e}</Increment><Offset>0</Offset></CX>
      <CY><AxisType>I</AxisType><DataType>D</DataType><Increment>{DX:e}</Increment><Offset>0</Offset></CY>
      <CZ><AxisType>A</AxisType><DataType>D</DataType><Offset>0</Offset></CZ>
    </Axes>
  </Record1>
  <Record2>
    <Date>2026-11-30T00:00:00</Date>
    <Instrument><Manufacturer>goniospec</Manufacturer><Model>synthetic AFM scan</Model><Serial>1</Serial><Version>1</Version></Instrument>
    <CalibrationDate>2026-11-30T00:00:00</CalibrationDate>
    <ProbingSystem><Type>Contacting</Type><Identification>synthetic</Identification></ProbingSystem>
    <Comment>scripts/make-measured-sample.py: gold grains, residual tilt, 12 drop-outs</Comment>
  </Record2>
  <Record3>
    <MatrixDimension><SizeX>{NX}</SizeX><SizeY>{NY}</SizeY><SizeZ>1</SizeZ></MatrixDimension>
    <DataLink><PointDataLink>bindata/data.bin</PointDataLink></DataLink>
  </Record3>
  <Record4><ChecksumFile>md5checksum.hex</ChecksumFile></Record4>
</p:ISO5436_2>
"""

out = Path(__file__).resolve().parent.parent / "meshes" / "afm-gold-scan.x3p"
tmp = out.with_suffix(".x3p.tmp")
with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
    for name, payload in [("main.xml", xml.encode()), ("bindata/data.bin", data)]:
        info = zipfile.ZipInfo(name, date_time=(2026, 11, 30, 0, 0, 0))
        info.compress_type = zipfile.ZIP_DEFLATED
        zf.writestr(info, payload)
tmp.replace(out)
print(f"wrote {out} ({out.stat().st_size} bytes)")
