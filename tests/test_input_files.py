"""Files a user hands to gpfverify that are not what they claim: devices, pipes and folders are
refused without reading or blocking; npz archives are judged by their headers before any data
is decompressed; case files with duplicate or unknown keys are refused, and a number written as
an integer literal is the number it is. The command line exits 2 with one line and writes
nothing."""

import io
import json
import os
import re
import struct
import subprocess
import sys
import warnings
import zipfile

import numpy as np
import pytest

from gpfverify import userfiles
from gpfverify.cli import main
from gpfverify.errors import CaseFileError, InputError
from gpfverify.fusion.case import case_to_dict
from gpfverify.fusion.caseblock import load_case
from gpfverify.audit.runfile import write_run
from gpfverify.fusion.synthetic import random_case
from gpfverify.userfiles import read_npz


def _case_text(**extra) -> str:
    return json.dumps({**case_to_dict(random_case(np.random.default_rng(0), 2, (1, 2))), **extra})


def _refused(argv, capsys, needle: str, folder=None):
    before = sorted(folder.iterdir()) if folder is not None else None
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert needle in err, err
    if folder is not None:
        assert sorted(folder.iterdir()) == before


@pytest.mark.parametrize("suffix", [".json", ".jsonl", ".npz"])
def test_devices_folders_and_links_to_devices_are_refused(tmp_path, capsys, suffix):
    link = tmp_path / f"random{suffix}"
    link.symlink_to("/dev/urandom")
    _refused(["audit", str(link), "--json"], capsys, "is a character device, not a regular file", tmp_path)
    folder = tmp_path / f"folder{suffix}"
    folder.mkdir()
    _refused(["audit", str(folder)], capsys, "is a folder, not a regular file", tmp_path)
    if suffix == ".json":
        _refused(["fuse", str(link), "--method", "dmf"], capsys, "not a regular file", tmp_path)


def test_a_named_pipe_without_a_writer_is_refused_at_once(tmp_path):
    """In a real process with a time limit: the old reader blocked forever on the open."""
    pipe = tmp_path / "run.jsonl"
    os.mkfifo(pipe)
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "audit", str(pipe), "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stdout == "" and proc.stderr.count("\n") == 1
    assert "is a named pipe, not a regular file" in proc.stderr


def test_npz_declared_sizes_are_checked_before_reading(tmp_path, monkeypatch):
    path = tmp_path / "big.npz"
    np.savez_compressed(path, y=np.zeros((1000, 1000)))  # 8 MB declared, a few kB on disk
    assert path.stat().st_size < 100_000
    assert read_npz(path)["y"].shape == (1000, 1000)
    with pytest.raises(CaseFileError, match=r"array y has shape \(1000, 1000\), expected \(\?, 3\)"):
        read_npz(path, {"y": (None, 3)})
    monkeypatch.setattr(userfiles, "memory_budget", lambda: 1_000_000)
    read = []
    monkeypatch.setattr(userfiles.NpzArchive, "_read_into", lambda *a: read.append(a))
    with pytest.raises(CaseFileError, match=r"declare 8\.0 MB .* more than this machine can hold now \(1\.0 MB\)"):
        read_npz(path)
    assert read == []  # refused from the header: no data was decompressed


def test_npz_whose_header_lies_about_its_data_is_refused(tmp_path):
    """A member declaring 8 GB next to a few bytes of data (a damaged archive or a bomb)."""
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z, z.open("y.npy", "w") as member:
        np.lib.format.write_array_header_1_0(member, {"descr": "<f8", "fortran_order": False,
                                                      "shape": (1_000_000_000,)})
        member.write(b"\0" * 64)
    with pytest.raises(CaseFileError, match=r"declares shape \(1000000000,\) \(8\.0 GB\)"):
        read_npz(path)


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 truncated", "half", "pickle"])
def test_empty_truncated_and_pickled_npz_are_input_errors(tmp_path, capsys, content):
    path = tmp_path / "run.npz"
    if content == "half":
        write_run(tmp_path / "good.npz", [random_case(np.random.default_rng(1), 2, (1, 1))])
        data = (tmp_path / "good.npz").read_bytes()
        path.write_bytes(data[: len(data) - 40])
        (tmp_path / "good.npz").unlink()
    elif content == "pickle":
        np.savez(path, y=np.array([None, 1], dtype=object))
    else:
        path.write_bytes(content)
    with pytest.raises(CaseFileError, match="run.npz"):
        read_npz(path)
    _refused(["audit", str(path)], capsys, "run.npz", tmp_path)


def _damaged(path, how: str) -> None:
    """A compressed npz whose member ``y.npy`` is damaged ``how``: one byte of its data flipped, its
    deflate stream broken at the start, or marked encrypted; or an archive with two members ``y.npy``."""
    ys = np.random.default_rng(0).normal(size=(50, 4))
    if how == "two-of-one-name":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # zipfile's "Duplicate name" as it writes them
            with zipfile.ZipFile(path, "w") as z:
                for values in (ys, ys + 100.0):
                    buffer = io.BytesIO()
                    np.save(buffer, values)
                    z.writestr("y.npy", buffer.getvalue())
        return
    np.savez_compressed(path, y=ys)
    data = bytearray(path.read_bytes())
    info = zipfile.ZipFile(path).getinfo("y.npy")
    name_length, extra_length = struct.unpack("<HH", data[info.header_offset + 26:info.header_offset + 30])
    start = info.header_offset + 30 + name_length + extra_length
    if how == "flipped-byte":
        data[start + info.compress_size // 2] ^= 0x55
    elif how == "bad-deflate":
        data[start:start + 6] = b"\xff" * 6
    else:  # encrypted: the flag in the local and the central header
        data[info.header_offset + 6] |= 1
        central = data.rfind(b"PK\x01\x02")
        data[central + 8] |= 1
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("how, said", [("flipped-byte", "array y cannot be read, the archive is damaged: Bad CRC-32"),
                                       ("bad-deflate", "array y cannot be read, the archive is damaged: Error -3"),
                                       ("encrypted", "array y is encrypted"),
                                       ("two-of-one-name", "holds two arrays named 'y'")])
def test_a_damaged_encrypted_or_ambiguous_npz_is_refused_in_one_line(tmp_path, capsys, how, said):
    path = tmp_path / "m.npz"
    _damaged(path, how)
    with pytest.raises(CaseFileError, match=re.escape(said)):
        read_npz(path)
    system = tmp_path / "linear.py"
    system.write_text("import numpy as np\nfrom gpfverify.models import linear_model\n"
                      "system = linear_model(np.eye(2), np.vstack([np.eye(2), np.eye(2)]), np.eye(2), np.eye(4), "
                      "prior_mean=[0, 0], prior_cov=np.eye(2), sizes=(2, 2))\n")
    _refused(["check", f"{system}:system", "--measurements", str(path), "--json"], capsys, said, tmp_path)
    _refused(["audit", str(path)], capsys, said, tmp_path)


@pytest.mark.parametrize("part", ["prior_mean", "prior_cov", "process_cov", "transition", "noise_cov"])
def test_complex_numbers_anywhere_in_a_model_are_refused_not_truncated(part):
    """numpy turns a complex array into floats by dropping the imaginary parts (with a warning):
    a model given one is refused, as a complex transition always was."""
    from gpfverify.models import Sensor, StateSpaceModel

    parts = {"prior_mean": np.zeros(2), "prior_cov": np.eye(2), "process_cov": 0.1 * np.eye(2),
             "transition": np.eye(2), "noise_cov": np.eye(2)}
    parts[part] = parts[part] + 1e-3j
    with pytest.raises(InputError, match=r"must be numeric \(real numbers\), got complex numbers"):
        StateSpaceModel(transition=parts["transition"], process_cov=parts["process_cov"],
                        sensors=[Sensor(np.eye(2), parts["noise_cov"])], prior_mean=parts["prior_mean"],
                        prior_cov=parts["prior_cov"])


def test_duplicate_keys_are_refused_wherever_they_are(tmp_path, capsys):
    text = _case_text()
    variants = {"top": text[:-1] + ', "y": [1.0, 2.0, 3.0]}',
                "central": text.replace('"central": {', '"central": {"mu_p": [0.0, 0.0], ', 1),
                "local": text.replace('"locals": [{', '"locals": [{"C_y": [[1.0]], ', 1)}
    for where, bad in variants.items():
        path = tmp_path / f"{where}.json"
        path.write_text(bad)
        assert json.loads(bad)  # Python's json reads it (the last key wins)
        key = {"top": "y", "central": "mu_p", "local": "C_y"}[where]
        with pytest.raises(CaseFileError, match=f"the key '{key}' appears twice"):
            load_case(path)
        _refused(["audit", str(path), "--json"], capsys, "appears twice")
        path.unlink()
    run = tmp_path / "run.jsonl"
    run.write_text(text + "\n" + variants["local"] + "\n")
    _refused(["audit", str(run), "--json"], capsys, "line 2: the key 'C_y' appears twice", tmp_path)


def test_unknown_keys_are_refused_with_the_known_ones_named(tmp_path, capsys):
    path = tmp_path / "case.json"
    path.write_text(_case_text(Y=[1.0, 2.0, 3.0]))
    _refused(["audit", str(path)], capsys, "has an unknown key 'Y' (the keys there are central, locals, y, rank_tol")
    data = json.loads(_case_text())
    data["locals"][1]["Ce"] = data["locals"][1].pop("C_e")
    path.write_text(json.dumps(data))
    _refused(["fuse", str(path), "--method", "ci"], capsys, "locals[1] has an unknown key 'Ce'")


def test_numbers_are_json_numbers_whatever_their_spelling(tmp_path, capsys):
    path = tmp_path / "case.json"
    path.write_text(_case_text()[:-1] + ', "rank_tol": 100000000000000000000}')
    assert load_case(path).rank_tol == 1e20
    assert main(["audit", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["rank_rule"]["tol"] == 1e20
    for bad, needle in (('"rank_tol": "1e-9"', "rank_tol must be a number, got a string"),
                        ('"rank_tol": true', "rank_tol must be a number, got a boolean"),
                        ('"rank_tol": 1' + "0" * 101, "rank_tol is outside the accepted range")):
        path.write_text(_case_text()[:-1] + ", " + bad + "}")
        _refused(["audit", str(path)], capsys, needle)
