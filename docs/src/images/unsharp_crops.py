"""The manual's before/after crop (docs/src/images/unsharp-before-after.png).

Run 0 at the ×1 exposure of biplanar_realistic and of biplanar_realistic_blurred, e.g.:

    for f in biplanar_realistic biplanar_realistic_blurred; do
      sed -e 's/^exposure_levels = .*/exposure_levels = [1.0]/; s/^runs_per_level = .*/runs_per_level = 1/' \
        scenarios/$f.toml > scenarios/_tmp_$f.toml
      cargo run --release -- scenarios/_tmp_$f.toml --out /tmp/crop_$f
    done
    python3 docs/src/images/unsharp_crops.py /tmp/crop_biplanar_realistic /tmp/crop_biplanar_realistic_blurred

A 56 × 56 px window of image model-det1 (rows 818-873, columns 734-789: the femoral component's
lower edge and the markers K2 and K1), each side windowed to its own 1st-99.9th percentile,
enlarged 6× (nearest neighbour). Needs numpy and Pillow.
"""

import sys

import numpy as np
from PIL import Image

ROW, COL, SIZE, SCALE = 818, 734, 56, 6


def tile(folder):
    a = np.array(Image.open(f"{folder}/runs/n0-r00/model-det1.tiff")).astype(float)
    c = a[ROW : ROW + SIZE, COL : COL + SIZE]
    lo, hi = np.percentile(c, 1), np.percentile(c, 99.9)
    c = np.clip((c - lo) / (hi - lo), 0, 1) * 255
    return Image.fromarray(c.astype(np.uint8)).resize((SIZE * SCALE, SIZE * SCALE), Image.NEAREST)


def main():
    sharp, blurred = tile(sys.argv[1]), tile(sys.argv[2])
    out = Image.new("L", (sharp.width * 2 + 12, sharp.height), 255)
    out.paste(sharp, (0, 0))
    out.paste(blurred, (sharp.width + 12, 0))
    out.save("docs/src/images/unsharp-before-after.png", optimize=True)


if __name__ == "__main__":
    main()
