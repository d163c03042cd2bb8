#!/usr/bin/env python3
"""An IMU record of the R package imudata (SMAC-Group, https://github.com/SMAC-Group/imudata)
as a CSV table `imunoise` reads: header `gx,gy,gz,ax,ay,az`, rad/s and m/s^2.

The package's ADIS16405 records (`data/adis_16405_imu1.rda` .. `imu6.rda`, 1e6 samples at
100 Hz from a static sensor, Department of Geomatics Engineering, University of Calgary) are
licensed CC BY-NC-SA 4.0, so the project does not ship them; docs/guide/analysis.md reports
what `analyze` and `model` find in them. Their columns are "Gyro. X/Y/Z" and "Accel. X/Y/Z"
without units. The gyro values are multiples of 0.05 (the ADIS16405's 0.05 deg/s LSB) and the
accelerometer's of 0.00333 (its 3.33 mg LSB), with az near -1: deg/s and g, which the white
levels confirm (2.3-2.6 deg/sqrt(h) against the data sheet's 2.0).

Usage (pip install rdata numpy):

    python3 scripts/imudata_to_csv.py adis_16405_imu1.rda adis1.csv
    imunoise analyze adis1.csv --rate 100

A record with other columns (one gyro axis, as `cont.imu1`) is written with as many of the
names, in order, as it has columns; `--units si` keeps the values as stored.
"""
import argparse

import numpy as np
import rdata

DEG = np.pi / 180.0
# Standard gravity, m/s^2 (CGPM 1901).
G = 9.80665
NAMES = ["gx", "gy", "gz", "ax", "ay", "az"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rda")
    parser.add_argument("csv")
    parser.add_argument("--units", choices=["deg-g", "si"], default="deg-g",
                        help="the stored units: deg/s and g (the ADIS16405 records), or SI")
    args = parser.parse_args()
    converted = rdata.conversion.convert(rdata.parser.parse_file(args.rda))
    (values,) = converted.values()
    a = np.asarray(values, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    if a.shape[1] > len(NAMES):
        raise SystemExit(f"{args.rda}: {a.shape[1]} columns, at most {len(NAMES)} expected")
    if args.units == "deg-g":
        scale = np.array([DEG, DEG, DEG, G, G, G])[: a.shape[1]]
        a = a * scale
    names = NAMES[: a.shape[1]]
    np.savetxt(args.csv, a, delimiter=",", header=",".join(names), comments="", fmt="%.9g")
    print(f"{args.csv}: {a.shape[0]} rows, columns {','.join(names)}")


if __name__ == "__main__":
    main()
