"""``tracker audio locate``: the JSON contract, the readable summary and one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tracker.audio import room
from tracker.audio.array import load_array
from tracker.audio.head_room import simulate_head_mounted
from tracker.audio.sources import write_wav
from tracker.audio.speech import synthetic_speech
from tracker.cli import main

from .conftest import ARRAYS_DIR, FS_HZ, example_array

SQUARE = str(ARRAYS_DIR / "square4_65mm.json")


@pytest.fixture(scope="module")
def recording_wav(tmp_path_factory):
    """3 s of a talker at 35° in a 0.3 s RT60 room, 20 dB SNR, as a 4-channel 16-bit WAV."""
    array = example_array("square4_65mm")
    settings = room.RoomSettings(rt60_s=0.3, snr_db=20.0)
    placement = room.centre_placement(settings)
    speech = synthetic_speech(3.0, FS_HZ, seed=21)
    position = room.position_from_direction(placement, np.deg2rad(35.0), 1.5)
    recording = room.simulate(settings, array, placement,
                              [room.static_talker(speech.samples, speech.active, position)])
    path = tmp_path_factory.mktemp("audio") / "talker35.wav"
    write_wav(path, FS_HZ, recording.audio)
    return str(path)


def test_locate_json_contract(recording_wav, capsys):
    assert main(["audio", "locate", recording_wav, "--array", SQUARE, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"fs", "frames", "track"}
    assert data["fs"] == FS_HZ and isinstance(data["fs"], int)
    assert len(data["frames"]) == len(data["track"]) > 10
    for frame in data["frames"]:
        assert set(frame) == {"t", "azimuth_deg", "elevation_deg", "confidence", "speech"}
        assert isinstance(frame["t"], float) and isinstance(frame["azimuth_deg"], float)
        assert frame["elevation_deg"] is None  # flat array
        assert isinstance(frame["speech"], bool) and 0.0 <= frame["confidence"] <= 1.0
    for point in data["track"]:
        assert set(point) == {"t", "azimuth_deg", "elevation_deg"}
    speech_az = [f["azimuth_deg"] for f in data["frames"] if f["speech"]]
    assert len(speech_az) > 10
    assert abs(np.median(speech_az) - 35.0) < 4.0
    assert abs(data["track"][-1]["azimuth_deg"] - 35.0) < 5.0


@pytest.mark.parametrize("method", ["seed_rms", "gcc_phat", "srp_dpd"])
def test_every_method_runs_from_the_command_line(recording_wav, capsys, method):
    assert main(["audio", "locate", recording_wav, "--array", SQUARE, "--method", method,
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["frames"]


@pytest.mark.parametrize("tracker", ["auto", "map", "kalman"])
def test_both_trackers_frame_the_talker_from_the_command_line(recording_wav, capsys, tracker):
    """``--front-only`` with srp_phat and a room array takes the map tracker by default; either
    tracker ends on the talker at 35°."""
    assert main(["audio", "locate", recording_wav, "--array", SQUARE, "--front-only",
                 "--tracker", tracker, "--json"]) == 0
    track = json.loads(capsys.readouterr().out)["track"]
    assert abs(track[-1]["azimuth_deg"] - 35.0) < 5.0


def test_the_map_tracker_with_another_localizer_is_a_one_line_error(recording_wav, capsys):
    assert main(["audio", "locate", recording_wav, "--array", SQUARE, "--method", "gcc_phat",
                 "--tracker", "map"]) == 2
    assert "srp_phat" in _error_line(capsys)


def test_readable_summary(recording_wav, capsys):
    assert main(["audio", "locate", recording_wav, "--array", SQUARE]) == 0
    out = capsys.readouterr().out
    assert "srp_phat" in out and "camera ->" in out


def _error_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("error: ")
    return lines[0]


def test_wrong_channel_count(tmp_path, recording_wav, capsys):
    six = str(ARRAYS_DIR / "circular6_46mm.json")
    assert main(["audio", "locate", recording_wav, "--array", six]) == 2
    line = _error_line(capsys)
    assert "4 channel(s)" in line and "6 mics" in line


def test_unreadable_wav(tmp_path, capsys):
    bad = tmp_path / "notes.wav"
    bad.write_text("this is not audio")
    assert main(["audio", "locate", str(bad), "--array", SQUARE]) == 2
    assert "not a readable WAV file" in _error_line(capsys)


def test_missing_wav(tmp_path, capsys):
    assert main(["audio", "locate", str(tmp_path / "nope.wav"), "--array", SQUARE]) == 2
    assert "file not found" in _error_line(capsys)


def test_silent_wav(tmp_path, capsys):
    path = tmp_path / "silence.wav"
    write_wav(path, FS_HZ, np.zeros((4, FS_HZ * 2)))
    assert main(["audio", "locate", str(path), "--array", SQUARE]) == 2
    assert "silent" in _error_line(capsys)


def test_too_short_wav(tmp_path, capsys):
    path = tmp_path / "short.wav"
    write_wav(path, FS_HZ, 0.1 * np.ones((4, 100)))
    assert main(["audio", "locate", str(path), "--array", SQUARE]) == 2
    assert "shorter than one" in _error_line(capsys)


def test_bad_array_file(tmp_path, recording_wav, capsys):
    path = tmp_path / "array.json"
    path.write_text(json.dumps({"mics": [[0, 0, 0]]}))
    assert main(["audio", "locate", recording_wav, "--array", str(path)]) == 2
    assert "at least 2 microphones" in _error_line(capsys)


# -- a head-mounted array: --encoder gives the head's angles; output stays in the base frame --

HEAD_T_S = np.array([0.0, 1.5, 2.1, 4.0])  # the head turns from -20° to 30° while she talks
HEAD_PAN_DEG = np.array([-20.0, -20.0, 30.0, 30.0])
HEAD_TILT_DEG = 10.0


@pytest.fixture(scope="module")
def head_recording(tmp_path_factory):
    """(wav, array json, encoder csv): a talker at 35° (base) heard by a head-mounted square."""
    folder = tmp_path_factory.mktemp("head")
    array_path = folder / "head_square.json"
    array_path.write_text(json.dumps({"mics": example_array("square4_65mm").positions_m.tolist(),
                                      "mount": "head"}))
    array = load_array(array_path)
    settings = room.RoomSettings(rt60_s=0.3, snr_db=20.0, ism_order=6)
    placement = room.centre_placement(settings)
    speech = synthetic_speech(4.0, FS_HZ, seed=8)
    position = room.position_from_direction(placement, np.deg2rad(35.0), 2.0)
    rec = simulate_head_mounted(settings, array, placement.position_m,
                                [room.static_talker(speech.samples, speech.active, position)],
                                HEAD_T_S, np.deg2rad(HEAD_PAN_DEG), np.full(4, np.deg2rad(HEAD_TILT_DEG)))
    wav = folder / "head.wav"
    write_wav(wav, FS_HZ, rec.audio)
    t = np.arange(0.0, 4.005, 0.01)
    encoder = folder / "encoder.csv"
    encoder.write_text("t,pan_deg,tilt_deg\n" + "".join(
        f"{x:.3f},{np.interp(x, HEAD_T_S, HEAD_PAN_DEG):.4f},{HEAD_TILT_DEG}\n" for x in t))
    return str(wav), str(array_path), str(encoder)


def test_locate_with_a_head_mounted_array_reports_the_base_frame(head_recording, capsys):
    wav, array, encoder = head_recording
    assert main(["audio", "locate", wav, "--array", array, "--encoder", encoder, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"fs", "frames", "track"}  # the contract is unchanged
    for frame in data["frames"]:
        assert set(frame) == {"t", "azimuth_deg", "elevation_deg", "confidence", "speech"}
    steady = [f["azimuth_deg"] for f in data["frames"]
              if f["speech"] and f["confidence"] > 0 and not 1.4 < f["t"] < 2.9]
    assert len(steady) > 10
    errors = np.abs(np.array(steady) - 35.0)
    assert np.median(errors) < 2.5, steady
    assert abs(data["track"][-1]["azimuth_deg"] - 35.0) < 5.0
    # Without the head's angles the same recording says 5° (35 - 30): the encoder did the work.
    plain = str(ARRAYS_DIR / "square4_65mm.json")
    assert main(["audio", "locate", wav, "--array", plain, "--json"]) == 0
    last = [f["azimuth_deg"] for f in json.loads(capsys.readouterr().out)["frames"]
            if f["speech"] and f["t"] > 2.9]
    assert abs(np.median(last) - 5.0) < 4.0


def test_a_head_mounted_array_without_encoder_angles_is_a_one_line_error(head_recording, capsys):
    wav, array, _ = head_recording
    assert main(["audio", "locate", wav, "--array", array]) == 2
    line = _error_line(capsys)
    assert "head_square.json is head-mounted" in line and "--encoder" in line


def test_encoder_angles_for_a_room_array_are_refused(head_recording, capsys):
    wav, _, encoder = head_recording
    assert main(["audio", "locate", wav, "--array", SQUARE, "--encoder", encoder]) == 2
    assert "room-mounted" in _error_line(capsys)


def test_an_encoder_log_that_stops_early_is_a_one_line_error(head_recording, tmp_path, capsys):
    wav, array, _ = head_recording
    short = tmp_path / "short.csv"
    short.write_text("t,pan,tilt\n0,0,0\n1.5,0.2,0\n")
    assert main(["audio", "locate", wav, "--array", array, "--encoder", str(short)]) == 2
    line = _error_line(capsys)
    assert "short.csv" in line and "0.00-1.50 s" in line and "0-4.00 s" in line


def test_auto_takes_the_map_tracker_where_the_localizer_gives_maps():
    from tracker.audio.pipeline import choose_tracker

    assert choose_tracker("srp_phat") == "map"  # any view: a limited one (a line) or a circle
    assert choose_tracker("gcc_phat") == "kalman" and choose_tracker("srp_dpd") == "kalman"


def test_a_head_mounted_array_takes_the_map_tracker_with_front_only(head_recording, capsys):
    """``--front-only`` keeps talkers in the base frame's front half: auto picks the map tracker
    for the head-mounted square, whose maps turn with the head (-20° -> 30°, tilted 10°)."""
    wav, array, encoder = head_recording
    assert main(["audio", "locate", wav, "--array", array, "--encoder", encoder, "--front-only",
                 "--json"]) == 0
    track = json.loads(capsys.readouterr().out)["track"]
    assert abs(track[-1]["azimuth_deg"] - 35.0) < 3.0
    late = [p["azimuth_deg"] for p in track if p["t"] > 2.5]
    assert late and max(abs(a - 35.0) for a in late) < 4.0, late


def test_a_head_mounted_array_tracks_all_round_without_front_only(head_recording, capsys):
    """The map tracker's base grid is a circle when the base view is the full circle."""
    wav, array, encoder = head_recording
    assert main(["audio", "locate", wav, "--array", array, "--encoder", encoder,
                 "--tracker", "map", "--json"]) == 0
    track = json.loads(capsys.readouterr().out)["track"]
    assert abs(track[-1]["azimuth_deg"] - 35.0) < 3.0