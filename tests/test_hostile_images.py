"""Images a careless or unlucky user hands over: huge headers, alpha, 16 bit, FIFOs (scene.images.read_rgb)."""

import os
import struct
import zlib

import cv2
import numpy as np
import pytest

from hvs_sim.cli import main
from hvs_sim.errors import InputError
from hvs_sim.scene.images import ALPHA_BACKGROUND, MAX_IMAGE_PIXELS, load_image, read_rgb


def _png_claiming(path, width, height):
    """A small valid PNG whose IHDR is rewritten to claim width × height (CRC fixed): the header lies."""
    _, buf = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))
    data = bytearray(buf.tobytes())
    ihdr = 8 + 8  # signature, then length and type of the IHDR chunk
    data[ihdr:ihdr + 8] = struct.pack(">II", width, height)
    data[ihdr + 13:ihdr + 17] = struct.pack(">I", zlib.crc32(bytes(data[ihdr - 4:ihdr + 13])))
    path.write_bytes(bytes(data))
    return path


@pytest.mark.parametrize("side", [100_000, 9_000])
def test_an_image_over_the_limit_is_refused_from_its_header(tmp_path, side):
    assert side * side > MAX_IMAGE_PIXELS
    p = _png_claiming(tmp_path / "huge.png", side, side)
    with pytest.raises(InputError, match="pixels accepted"):
        read_rgb(p)


def test_the_cli_refuses_a_huge_target_and_a_huge_frame_with_a_message(tmp_path, capsys):
    p = _png_claiming(tmp_path / "huge.png", 100_000, 100_000)
    assert main(["run", "--target-image", str(p), "--steps", "2"]) == 2
    assert "pixels accepted" in capsys.readouterr().err
    frames = tmp_path / "frames"
    frames.mkdir()
    _png_claiming(frames / "f0.png", 100_000, 100_000)
    assert main(["track", str(frames), "--roi", "0,0,30,30", "--out", str(tmp_path / "out")]) == 2
    assert "pixels accepted" in capsys.readouterr().err


def test_alpha_is_composited_over_white_and_16_bit_data_is_scaled_by_its_range(tmp_path, caplog, monkeypatch):
    from hvs_sim.scene import images

    monkeypatch.setattr(images, "_NOTED", set())
    rgba = np.zeros((40, 40, 4), np.uint8)
    rgba[..., 2] = 200  # red (BGR order on disk)
    rgba[:, :20, 3] = 255  # left half opaque, right half transparent
    cv2.imwrite(str(tmp_path / "a.png"), rgba)
    img = load_image(tmp_path / "a.png")
    assert img[5, 5].tolist() == [200, 0, 0] and img[5, 35].tolist() == [ALPHA_BACKGROUND] * 3
    twelve = np.full((40, 40, 3), 4095, np.uint16)
    twelve[:, :20] = 2048
    cv2.imwrite(str(tmp_path / "b.png"), twelve)
    img = read_rgb(tmp_path / "b.png")
    assert img[0, 39].tolist() == [255] * 3 and abs(int(img[0, 0, 0]) - 128) <= 1  # 12-bit data, not near black
    assert "16-bit image holding 12-bit data (largest value 4095): scaled by 255/4095" in caplog.text
    caplog.clear()
    read_rgb(tmp_path / "b.png")
    assert "16-bit" not in caplog.text  # said once, not once a frame
    full = np.full((40, 40, 3), 65535, np.uint16)
    cv2.imwrite(str(tmp_path / "c.png"), full)
    assert read_rgb(tmp_path / "c.png")[0, 0].tolist() == [255] * 3


def test_a_fifo_or_a_folder_is_refused_not_waited_on(tmp_path):
    fifo = tmp_path / "x.png"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="not a regular file"):
        read_rgb(fifo)
    with pytest.raises(InputError, match="not a regular file"):
        read_rgb(tmp_path)


def test_track_refuses_a_fifo_named_like_a_video(tmp_path, capsys):
    fifo = tmp_path / "clip.mp4"
    os.mkfifo(fifo)
    assert main(["track", str(fifo), "--roi", "0,0,30,30", "--out", str(tmp_path / "out")]) == 2
    assert "not a regular file" in capsys.readouterr().err


def test_a_failed_write_names_the_file_and_keeps_the_previous_one(tmp_path, monkeypatch):
    import errno

    from hvs_sim import outputs
    from hvs_sim.errors import OutputError
    from hvs_sim.manifest import MANIFEST_NAME
    from hvs_sim.outputs import write_atomic

    target = tmp_path / "summary.json"
    write_atomic(target, "complete")

    def full_disk(path, need_bytes, native=True):  # the output layer's writes meet a full disk
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs, "ensure_space", full_disk)
    with pytest.raises(OutputError, match="summary.json .No space left on device.; the previous complete file is kept"):
        write_atomic(target, "new")
    monkeypatch.undo()
    assert target.read_text() == "complete"
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST_NAME, "summary.json"]


def test_track_says_when_a_video_decodes_fewer_frames_than_its_header(tmp_path, capsys):
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (96, 96))
    rng = np.random.default_rng(0)
    base = cv2.GaussianBlur(rng.integers(0, 255, (96, 96, 3), np.uint8), (0, 0), 2)
    for k in range(30):
        writer.write(np.roll(base, k, axis=1))
    writer.release()
    data = path.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: len(data) * 9 // 10])  # a truncated download: the header still says 30 frames
    assert main(["track", str(cut), "--roi", "30,30,40,40", "--out", str(tmp_path / "o"), "--tracker", "ecc"]) == 0
    out = capsys.readouterr().out
    assert "note: the video's header says 30 frames; only 27 could be decoded" in out


def test_scene_refuses_an_out_inside_its_wall_pictures(tmp_path, capsys):
    pics = tmp_path / "pics"
    pics.mkdir()
    for k in range(2):
        cv2.imwrite(str(pics / f"p{k}.png"), np.random.default_rng(k).integers(0, 255, (80, 120, 3), np.uint8))
    before = sorted(p.name for p in pics.iterdir())
    assert main(["scene", "--wall-images", str(pics), "--out", str(pics / "out"), "--frames", "1"]) == 2
    assert "lies inside the input" in capsys.readouterr().err and sorted(p.name for p in pics.iterdir()) == before
