"""Recordings and run directories as a careless or hostile user hands them over (docs/reliability/
adversarial_inference.md): each is one InputError or ConfigError naming it, never a traceback, other weights or
another reading of the data."""

import os
import shutil

import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import readers
from hybrid_sysid.inference.inputs import InputError
from hybrid_sysid.runs.rundir import RunDir

from helpers.estimator_run import predict, recordings

DT = 0.005  # data=tiny's, the trained run's


def npz(path, **arrays):
    np.savez(path, **arrays)
    return path


def test_npz_members_that_cannot_be_read_are_one_line(tmp_path, capsys):
    seat = np.sin(np.arange(400) * 0.1)
    whole = npz(tmp_path / "whole.npz", seat_acc=seat, body_acc=seat, dt=DT)
    data = bytearray(whole.read_bytes())
    data[len(data) // 2] ^= 0xFF  # inside body_acc's bytes: its CRC no longer matches
    damaged = {
        "object.npz": npz(tmp_path / "object.npz", seat_acc=np.array([seat, None], dtype=object), body_acc=seat, dt=DT),
        "crc.npz": tmp_path / "crc.npz",
        "cut.npz": tmp_path / "cut.npz",
    }
    damaged["crc.npz"].write_bytes(bytes(data))
    damaged["cut.npz"].write_bytes(whole.read_bytes()[:-40])
    for name, path in damaged.items():
        # input= is read before the run: no run is needed to see the refusal
        code, out, err = predict(capsys, f"run={tmp_path / 'no_run'}", f"input={path}")
        assert code == 2 and out == "", (name, err)
        assert len(err.splitlines()) == 1 and name in err and "Traceback" not in err, err


def test_an_npz_array_the_command_does_not_read_is_never_loaded(tmp_path):
    seat = np.sin(np.arange(400) * 0.1)
    path = npz(tmp_path / "extra.npz", seat_acc=seat, body_acc=seat, dt=DT, meta=np.array([{"a": 1}], dtype=object))
    got = readers.read_input(path)
    assert got.dt == DT and np.array_equal(got.seat, seat) and np.array_equal(got.body, seat)


def test_an_npz_array_declaring_more_than_the_memory_available_is_refused_before_it_is_unpacked(tmp_path, monkeypatch):
    # a compressed member unpacks to what its header declares: here 2 MiB against a limit of 1 MiB
    path = tmp_path / "bomb.npz"
    np.savez_compressed(path, seat_acc=np.zeros(2**18), body_acc=np.zeros(2**18), dt=DT)
    assert path.stat().st_size < 2**16
    monkeypatch.setattr(readers, "tightest_memory", lambda: (2**20, "a test's limit"))

    def unpacked(*args, **kwargs):
        raise AssertionError("the array was unpacked")

    monkeypatch.setattr(np.lib.format, "read_array", unpacked)
    with pytest.raises(InputError, match=r"array seat_acc = shape \(262144,\).*a test's limit"):
        readers.read_input(path)


def test_recording_names_are_read_as_written(tmp_path):
    # read as numbers, "7" and "007" (or "1" and "1.0") would be one recording of both's rows
    seat = np.sin(np.arange(400) * 0.1)
    frames = [
        pd.DataFrame({"recording": name, "seat_acc": seat, "body_acc": seat}) for name in ("7", "007", "1.0", "1")
    ]
    path = tmp_path / "names.csv"
    pd.concat(frames).to_csv(path, index=False)
    got = readers.read_input(path, DT)
    assert got.names == ["7", "007", "1.0", "1"] and [len(s) for s in got.seat] == [400] * 4


def test_resample_must_be_true_or_false(est):
    # a recording at twice the run's dt: resample="false" is a true value and would resample it
    seat, body, _ = recordings(1, 800, 2 * DT)
    with pytest.raises(InputError, match="resample = 'false' is not allowed: True or False"):
        est.predict(seat[0], body[0], 2 * DT, resample="false")
    assert len(est.predict(seat[0], body[0], 2 * DT, resample=np.bool_(True))) == 1


def test_a_masked_array_with_masked_values_is_refused(est):
    seat, body, _ = recordings(1, 400, DT)
    gap = np.ma.masked_array(seat[0], mask=np.arange(400) % 50 == 0)
    with pytest.raises(InputError, match="seat_acc = a masked array with masked values is not allowed"):
        est.predict(gap, body[0], DT)
    whole = est.predict(np.ma.masked_array(seat[0]), body[0], DT)  # nothing masked: the values themselves
    assert whole.p1.item() == est.predict(seat[0], body[0], DT).p1.item()


@pytest.mark.parametrize("kind", ["fifo", "folder", "device", "dangling link"])
def test_a_best_checkpoint_that_is_not_a_regular_file_is_refused_not_replaced_by_last(tiny_run, tmp_path, kind):
    from hybrid_sysid import load_estimator

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run, ignore=shutil.ignore_patterns("*.lock"))
    best = run / "checkpoints" / "best.ckpt"
    best.unlink()
    if kind == "fifo":
        os.mkfifo(best)
    elif kind == "folder":
        best.mkdir()
    else:
        best.symlink_to("/dev/zero" if kind == "device" else run / "gone.ckpt")
    with pytest.raises(ConfigError, match="checkpoints/best.ckpt is a regular file"):
        RunDir(run).trained_checkpoint()
    with pytest.raises(InputError, match="checkpoints/best.ckpt is a regular file"):
        load_estimator(run)
    assert RunDir(run).trained_checkpoint(which="last").name == "last.ckpt"  # asked for: still there


@pytest.mark.parametrize("kind", ["fifo", "link to stdout", "link to a file"])
def test_output_is_never_put_in_a_links_or_a_fifos_place(tmp_path, capsys, kind):
    # output=/dev/stdout overwrite=true, run as root, would rename a file over /dev's link
    seat = np.sin(np.arange(400) * 0.1)
    recording = npz(tmp_path / "drive.npz", seat_acc=seat, body_acc=seat, dt=DT)
    output = tmp_path / "out.csv"
    if kind == "fifo":
        os.mkfifo(output)
    else:
        (tmp_path / "table.csv").write_text("kept\n")
        output.symlink_to("/proc/self/fd/1" if kind == "link to stdout" else tmp_path / "table.csv")
    code, out, err = predict(
        capsys, f"run={tmp_path / 'no_run'}", f"input={recording}", f"output={output}", "overwrite=true"
    )
    assert code == 2 and out == "" and len(err.splitlines()) == 1, err
    assert "it is a symbolic link, FIFO or device" in err
    assert output.is_symlink() if kind != "fifo" else output.is_fifo()
    assert kind == "fifo" or (tmp_path / "table.csv").read_text() == "kept\n"


def test_a_received_config_asking_for_a_huge_network_is_refused_before_it_is_built(tiny_run, tmp_path):
    # 200,000 channels: 1.4 TB of weights, which the checks would build for real; the checkpoint holds 32
    from hybrid_sysid import load_estimator

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run, ignore=shutil.ignore_patterns("*.lock"))
    config = run / ".hydra" / "config.yaml"
    text = config.read_text()
    assert "\n    channels: 32\n" in text
    config.write_text(text.replace("\n    channels: 32\n", "\n    channels: 200000\n"))
    # refused by the cap on a network's weights (1e8), before anything is built or compared with the checkpoint
    with pytest.raises(InputError, match=r"model\.net\.channels = 200000 is not allowed: .* at most 1e\+08 weights"):
        load_estimator(run)


def test_ctrl_c_while_torch_is_imported_is_one_line_and_status_130(tmp_path, capsys, monkeypatch):
    # the console script imports the command's module, then calls main(): torch and Lightning, seconds of import
    # on a busy machine, must load inside main(), whose Ctrl-C is one line and exit 130, not an 80-line traceback
    import importlib.abc
    import subprocess
    import sys

    probe = (
        "import sys; from hybrid_sysid.cli.predict import main; print(sorted({'torch', 'pandas'} & set(sys.modules)))"
    )
    assert subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout == "[]\n"

    class CtrlC(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "hybrid_sysid.inference.loading":
                raise KeyboardInterrupt
            return None

    monkeypatch.delitem(sys.modules, "hybrid_sysid.inference.loading", raising=False)
    monkeypatch.setattr(sys, "meta_path", [CtrlC(), *sys.meta_path])
    seat = np.sin(np.arange(400) * 0.1)
    recording = npz(tmp_path / "drive.npz", seat_acc=seat, body_acc=seat, dt=DT)
    code, out, err = predict(capsys, f"run={tmp_path / 'run'}", f"input={recording}", f"output={tmp_path / 'out.csv'}")
    assert (code, out, err.splitlines()) == (130, "", ["hybrid-sysid-predict: interrupted (Ctrl-C)"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drive.npz"]


def test_a_constant_recording_the_network_cannot_read_is_not_called_an_overflow(est, monkeypatch):
    # model=anchored's least-squares gate is 0 / 0 on a constant recording: its NaN is no float32 overflow
    import torch

    class ZeroOverZero(torch.nn.Module):
        def forward(self, x):
            return torch.where(x.std(dim=2).amax(dim=1)[:, None] == 0, torch.nan, torch.ones(len(x), 2))

    monkeypatch.setattr(est, "net", ZeroOverZero())
    with pytest.raises(InputError, match=r"^recording 0 is not allowed: a recording with the motion the network") as e:
        est.predict(np.ones(400), np.ones(400), DT)
    assert "overflow" not in str(e.value) and "constant or zero recording" in str(e.value)


@pytest.mark.parametrize("run_dir", [None, b"outputs/runs/x", 3, ["outputs"]])
def test_a_run_dir_that_is_no_path_is_one_line_naming_it(run_dir):
    from hybrid_sysid import load_estimator

    with pytest.raises(InputError, match="run_dir") as caught:
        load_estimator(run_dir)
    assert "\n" not in str(caught.value) and "a str or a pathlib.Path" in str(caught.value)
