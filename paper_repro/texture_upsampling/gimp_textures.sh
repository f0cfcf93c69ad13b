#!/usr/bin/env bash
# Colour texture tiles from Debian's `gimp-data` package (GIMP's patterns, GPL: not
# committed), converted to PNG for `ifslab texture repro --data`: the kinds of texture the
# paper's Table I used (a woven floor, leaves, a brick wall, tiles), which our scikit-image
# textures are not. Downloads the package with `apt-get download` (no root needed), unpacks
# it with `dpkg -x`, and converts GIMP's .pat files (a big-endian header: header size,
# version, width, height, bytes per pixel, "GPAT", name; then the pixels) with Python's
# standard library. Output: target/gimp-textures/<name>.png (RGB).
#
#   paper_repro/texture_upsampling/gimp_textures.sh
#   ifslab texture repro --data target/gimp-textures --textures burlap,leaves,brick,... \
#     --tables-only --skip-ablation --out out/texture-gimp
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=target/gimp-textures
WORK=target/gimp-data
mkdir -p "$OUT" "$WORK"
if [ ! -d "$WORK/x/usr/share/gimp" ]; then
  (cd "$WORK" && apt-get download gimp-data >/dev/null && dpkg -x gimp-data_*.deb x)
fi
python3 - "$WORK/x/usr/share/gimp/2.0/patterns" "$OUT" <<'EOF'
import pathlib, struct, sys, zlib

src, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])

def png(path, w, h, rows):
    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    raw = b"".join(b"\0" + r for r in rows)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))

n = 0
for pat in sorted(src.rglob("*.pat")):
    b = pat.read_bytes()
    header, version, w, h, bpp = struct.unpack(">5I", b[:20])
    if b[20:24] != b"GPAT" or bpp not in (1, 3, 4):
        continue
    px = b[header:header + w * h * bpp]
    rows = []
    for y in range(h):
        r = px[y * w * bpp:(y + 1) * w * bpp]
        if bpp == 1:
            r = bytes(v for v in r for _ in range(3))
        elif bpp == 4:
            r = bytes(v for i, v in enumerate(r) if i % 4 != 3)
        rows.append(r)
    png(out / f"{pat.stem}.png", w, h, rows)
    n += 1
print(f"{n} textures in {out}")
EOF
