"""Reading pictures: every PIL mode, broken files, huge pictures, crop, decolorization."""

import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from stringbot.errors import BadInput
from stringbot.planner.picture.read import decolorize, parse_crop, read_mask, read_picture


def gradient_rgb(n=64):
    y, x = np.mgrid[:n, :n]
    return np.stack([x * 255 // (n - 1), y * 255 // (n - 1), np.full_like(x, 128)], axis=2).astype(np.uint8)


def save(tmp_path, name, im, **kw):
    path = tmp_path / name
    im.save(path, **kw)
    return path


def test_gray_png_is_read_as_is(tmp_path):
    g = np.tile(np.linspace(0, 255, 64).astype(np.uint8), (64, 1))
    pic = read_picture(save(tmp_path, "g.png", Image.fromarray(g)), size=64)
    assert pic.gray.shape == (64, 64) and pic.gray.dtype == np.float32
    assert np.abs(pic.gray - g).max() <= 2  # Lanczos at the same size: near identity
    assert pic.source["width"] == 64 and len(pic.source["sha256"]) == 64
    assert pic.crop == {"cx": 32.0, "cy": 32.0, "r": 32.0}


def test_16_bit_matches_8_bit(tmp_path):
    g8 = np.tile(np.linspace(0, 255, 64).astype(np.uint8), (64, 1))
    g16 = g8.astype(np.uint16) * 257
    a = read_picture(save(tmp_path, "a.png", Image.fromarray(g8)), size=32).gray
    b = read_picture(save(tmp_path, "b.png", Image.fromarray(g16)), size=32).gray
    assert Image.open(tmp_path / "b.png").mode.startswith("I")
    assert np.abs(a - b).max() <= 1.5


def test_transparent_pixels_count_as_white(tmp_path):
    rgba = np.zeros((64, 64, 4), dtype=np.uint8)  # black, fully transparent ...
    rgba[:, :32, 3] = 255                         # ... except the left half, opaque black
    pic = read_picture(save(tmp_path, "t.png", Image.fromarray(rgba, "RGBA")), size=64)
    assert pic.gray[:, :28].max() < 5 and pic.gray[:, 36:].min() > 250


def test_palette_with_transparency_and_la(tmp_path):
    p = Image.fromarray(gradient_rgb()).convert("P", palette=Image.Palette.ADAPTIVE, colors=16)
    p.info["transparency"] = 0
    a = read_picture(save(tmp_path, "p.png", p, transparency=0), size=32)
    assert a.gray.shape == (32, 32) and np.isfinite(a.gray).all()
    la = Image.fromarray(np.stack([np.zeros((32, 32), np.uint8), np.zeros((32, 32), np.uint8)], 2), "LA")
    assert read_picture(save(tmp_path, "la.png", la), size=32).gray.min() > 250  # all transparent: white


def test_cmyk_jpeg(tmp_path):
    rgb = Image.fromarray(gradient_rgb())
    pic = read_picture(save(tmp_path, "c.jpg", rgb.convert("CMYK"), quality=95), size=32, gray="luminance")
    ref = read_picture(save(tmp_path, "r.png", rgb), size=32, gray="luminance")
    assert np.abs(pic.gray - ref.gray).mean() < 12


def test_animated_gif_uses_the_first_frame(tmp_path):
    frames = [Image.new("L", (32, 32), v) for v in (0, 255)]
    path = tmp_path / "a.gif"
    frames[0].save(path, save_all=True, append_images=frames[1:])
    assert read_picture(path, size=32).gray.max() < 5


@pytest.mark.parametrize("maker, words", [
    (lambda p: p.write_bytes(b""), "empty file"),
    (lambda p: p.write_text("hello, not a picture"), "not a picture"),
    (lambda p: Image.new("L", (1, 1)).save(p, format="PNG"), "1 x 1"),
])
def test_unreadable_files_are_refused(tmp_path, maker, words):
    path = tmp_path / "bad.png"
    maker(path)
    with pytest.raises(BadInput, match=words):
        read_picture(path, size=32)


@pytest.mark.parametrize("fmt", ["PNG", "JPEG"])
def test_truncated_files_are_refused(tmp_path, fmt):
    path = tmp_path / f"t.{fmt.lower()}"
    Image.fromarray(gradient_rgb(128)).save(path, format=fmt)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(BadInput, match="truncated|damaged|cannot be read"):
        read_picture(path, size=32)


def test_missing_and_folder(tmp_path):
    with pytest.raises(BadInput, match="does not exist"):
        read_picture(tmp_path / "nope.png")
    with pytest.raises(BadInput, match="is a folder"):
        read_picture(tmp_path)


def huge_bilevel_png(path, side):
    """A side x side 1-bit PNG (black square in the middle), written row by row: small on disk."""
    row_bytes = (side + 7) // 8
    white = b"\x00" + b"\xff" * row_bytes
    black_mid = bytearray(white)
    for x in range(side // 4, 3 * side // 4):
        black_mid[1 + x // 8] &= ~(0x80 >> (x % 8)) & 0xFF
    comp = zlib.compressobj(6)
    chunks = []
    for y in range(side):
        chunks.append(comp.compress(bytes(black_mid) if side // 4 <= y < 3 * side // 4 else white))
    chunks.append(comp.flush())
    idat = b"".join(chunks)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 1, 0, 0, 0, 0))
           + chunk(b"IDAT", idat) + chunk(b"IEND", b""))
    path.write_bytes(png)


def test_huge_picture_is_read_downscaled_without_a_full_size_float_copy(tmp_path):
    import tracemalloc

    path = tmp_path / "huge.png"
    huge_bilevel_png(path, 20000)
    assert path.stat().st_size < 5_000_000
    tracemalloc.start()
    try:
        pic = read_picture(path, size=101)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 100_000_000  # numpy/Python allocations; a float copy would be 3.2 GB
    assert pic.source["width"] == 20000
    assert pic.gray[50, 50] < 10 and pic.gray[5, 5] > 245  # black middle, white corners


def test_crop_and_parse_crop(tmp_path):
    g = np.full((100, 200), 255, dtype=np.uint8)
    g[40:60, 160:180] = 0
    path = save(tmp_path, "w.png", Image.fromarray(g))
    centred = read_picture(path, size=50)
    assert centred.crop == {"cx": 100.0, "cy": 50.0, "r": 50.0}
    assert centred.gray.min() > 250  # the dark square is outside the centred circle
    moved = read_picture(path, size=50, crop=parse_crop("170,50,20"))
    assert moved.gray[25, 25] < 10
    edge = read_picture(path, size=50, crop=parse_crop("190,50,30"))  # reaches outside: white
    assert edge.gray[25, 49] > 250
    for bad in ("1,2", "a,b,c", "10,10,0", "10,10,-4"):
        with pytest.raises(BadInput, match="--crop"):
            parse_crop(bad)
    with pytest.raises(BadInput, match="outside"):
        read_picture(path, size=50, crop=parse_crop("500,500,10"))


def test_decolorization_keeps_an_isoluminant_contrast():
    # red and green patches of (nearly) equal luminance: plain luminance loses them
    img = np.zeros((64, 64, 3))
    img[:, :32] = (0.8, 0.2, 0.3)
    img[:, 32:] = (0.2, 0.5, 0.3)
    lum = np.array([0.299, 0.587, 0.114])
    w = np.array(decolorize(img))
    assert np.isclose(w.sum(), 1.0) and np.allclose(w * 10, np.round(w * 10)) and (w >= 0).all()
    contrast = abs((img[0, 0] - img[0, 63]) @ w)
    assert contrast > 3 * abs((img[0, 0] - img[0, 63]) @ lum)


def test_decolor_and_luminance_are_both_offered(tmp_path):
    img = np.zeros((64, 64, 3), dtype=np.uint8)
    img[:, :32] = (204, 51, 77)
    img[:, 32:] = (51, 128, 77)
    path = save(tmp_path, "c.png", Image.fromarray(img))
    dec = read_picture(path, size=32)
    lum = read_picture(path, size=32, gray="luminance")
    assert dec.gray_method == "decolor" and lum.gray_method == "luminance"
    assert abs(dec.gray[16, 4] - dec.gray[16, 28]) > 3 * abs(lum.gray[16, 4] - lum.gray[16, 28])


def test_mask_must_match_the_picture(tmp_path):
    Image.new("L", (64, 64), 255).save(tmp_path / "m.png")
    w = read_mask(tmp_path / "m.png", size=32, crop={"cx": 32, "cy": 32, "r": 32}, source_size=(64, 64))
    assert np.allclose(w, 2.0)
    Image.new("L", (64, 64), 0).save(tmp_path / "m0.png")
    assert np.allclose(read_mask(tmp_path / "m0.png", size=32, crop={"cx": 32, "cy": 32, "r": 32},
                                 source_size=(64, 64)), 1.0)
    with pytest.raises(BadInput, match="expected the picture's size 80 x 64"):
        read_mask(tmp_path / "m.png", size=32, crop={"cx": 40, "cy": 32, "r": 32}, source_size=(80, 64))


def test_exif_orientation_is_applied(tmp_path):
    g = np.full((60, 100), 255, dtype=np.uint8)  # landscape as stored ...
    g[:, :20] = 0                               # ... dark band on the left
    im = Image.fromarray(g)
    exif = Image.Exif()
    exif[0x0112] = 6  # shown turned 90 degrees clockwise: portrait, the band on top
    path = tmp_path / "o.jpg"
    im.save(path, exif=exif.tobytes(), quality=95)
    pic = read_picture(path, size=60, gray="luminance")
    assert pic.crop == {"cx": 30.0, "cy": 50.0, "r": 30.0}  # centred in the 60 x 100 portrait
    shown = read_picture(path, size=60, crop=parse_crop("30,10,10"))
    assert shown.gray.mean() < 40  # the dark band is at the top of the picture as shown


def test_big_jpeg_is_decoded_at_a_reduced_scale_with_the_same_result(tmp_path):
    y, x = np.mgrid[:1600, :2400]
    g = ((np.sin(x / 150.0) + np.cos(y / 110.0)) * 60 + 128).astype(np.uint8)
    Image.fromarray(g).save(tmp_path / "big.jpg", quality=95)
    Image.fromarray(g).save(tmp_path / "big.png")
    a = read_picture(tmp_path / "big.jpg", size=101, crop=parse_crop("1300,700,500"))
    b = read_picture(tmp_path / "big.png", size=101, crop=parse_crop("1300,700,500"))
    assert np.abs(a.gray - b.gray).mean() < 2.0
    assert a.source["width"] == 2400 and a.crop == {"cx": 1300.0, "cy": 700.0, "r": 500.0}
