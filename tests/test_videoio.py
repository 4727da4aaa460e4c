"""MP4s browsers play (H.264, yuv420p), read back; the mp4v fallback says it was used."""

import sys

import av
import cv2
import numpy as np

from hvs_sim.videoio import Mp4Writer


def _frames(n, h=71, w=97):
    rng = np.random.default_rng(0)
    base = cv2.GaussianBlur(rng.integers(0, 255, (h, w, 3), np.uint8), (0, 0), 2)
    return [np.roll(base, k, axis=1) for k in range(n)]


def test_h264_of_an_odd_size_is_written_and_read_back(tmp_path):
    path = tmp_path / "v.mp4"
    w = Mp4Writer(path, 30.0, (97, 71))
    frames = _frames(12)
    for f in frames:
        w.write(f)
    w.close()
    assert w.codec == "h264" and w.frames == 12
    with av.open(str(path)) as c:
        s = c.streams.video[0]
        assert s.codec_context.name == "h264" and s.format.name == "yuv420p" and (s.width, s.height) == (98, 72)
        decoded = [fr.to_ndarray(format="rgb24") for fr in c.decode(s)]
    assert len(decoded) == 12
    assert np.abs(decoded[5][:71, :97].astype(int) - frames[5]).mean() < 4  # near-lossless at CRF 18


def test_without_pyav_it_falls_back_to_mp4v_and_says_so(tmp_path, monkeypatch, caplog):
    monkeypatch.setitem(sys.modules, "av", None)  # import av now fails
    w = Mp4Writer(tmp_path / "v.mp4", 30.0, (96, 72))
    for f in _frames(3, 72, 96):
        w.write(f)
    w.close()
    assert w.codec == "mp4v" and "browsers do not play" in caplog.text
    cap = cv2.VideoCapture(str(tmp_path / "v.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 3
