"""``notchfit review`` without a browser: review.csv, the reviewed points in the fits, the angles by hand,
the corrections model with two tabs, the local-only server, Ctrl-C (issue 26)."""

import http.client
import json
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.cli import main
from notchfit.commands._points import source_lines
from notchfit.physics.geometry import default_geometry
from notchfit.physics.notches import notch_points, to_plane
from notchfit.review.measure import hand_angles, live_fit
from notchfit.review.server import ReviewHandler
from notchfit.units import MM
from reliability_helpers import cli_env
from review_helpers import BLANKED, rendered_study, running_server, work_copy


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    return rendered_study(tmp_path_factory.mktemp("review"))


# ----------------------------------------------------------------------------- review.csv
def _row(**kw):
    base = {"sample": 1, "point": 3, "u_px": 10.0, "v_px": 20.0, "x_mm": 1.5, "y_mm": -2.0, "sigma_mm": 0.03,
            "status": "manual", "prev_u_px": 11.0, "prev_v_px": 21.0, "prev_x_mm": 1.4, "prev_y_mm": -2.1,
            "prev_status": "ambiguous", "time": "2026-01-01T00:00:00+00:00"}
    return {**base, **kw}


def test_review_csv_round_trip_and_apply(tmp_path):
    rows = [_row(), _row(point=1, status="deleted", u_px=np.nan, v_px=np.nan, x_mm=np.nan, y_mm=np.nan,
                         sigma_mm=np.nan)]
    path = io.write_review(rows, tmp_path / "review.csv")
    df = io.read_review(path, n_points=58, sample_ids=[1, 2])
    assert list(df.columns) == list(io.REVIEW_COLUMNS)
    assert list(df["point"]) == [1, 3] and list(df["status"]) == ["deleted", "manual"]
    pts, sig = np.zeros((2, 58, 2)), np.full((2, 58), 1e-5)
    new, nsig = io.apply_review(pts, sig, df, [1, 2])
    assert np.isnan(new[0, 0]).all() and np.isnan(nsig[0, 0])
    np.testing.assert_allclose(new[0, 2], [1.5 * MM, -2.0 * MM])
    assert nsig[0, 2] == pytest.approx(0.03 * MM)
    assert (new[1] == 0).all() and (pts == 0).all()                       # the input is not changed


@pytest.mark.parametrize("change,message", [
    ({"status": "moved"}, "line 2: status 'moved' is not one of manual, deleted, occluded"),
    ({"x_mm": np.nan}, "line 2: a manual corner needs u_px, v_px, x_mm and y_mm"),
    ({"sigma_mm": 0.0}, "line 2: a manual corner needs a positive sigma_mm"),
    ({"point": 59}, "line 2: point id 59 out of range 1..58"),
])
def test_review_csv_errors_name_the_line(tmp_path, change, message):
    path = io.write_review([_row(**change)], tmp_path / "review.csv")
    with pytest.raises(io.InputFileError, match=message):
        io.read_review(path, n_points=58, sample_ids=[1])


# ----------------------------------------------------------------------------- measurements
@pytest.mark.parametrize("mirror", [False, True])
def test_hand_angles_recover_the_joint_angles(mirror):
    """The turn between neighbouring links, from their corners, is θ_j of the kinematics (Sec. II-A):
    exact for corners of the pivot model (notches.notch_points) in any plane pose, mirrored or not."""
    geom = default_geometry()
    theta = np.random.default_rng(7).normal(0.0, 0.05, geom.n_joints)
    Q = to_plane(notch_points(theta, geom), 0.012, -0.004, 2.1, mirror)
    res = hand_angles(Q, geom, mirror=mirror)
    np.testing.assert_allclose(res["theta"], theta, atol=1e-12)
    Q[4] = np.nan                                    # link 3 keeps one corner: joints 3 and 4 unknown
    res = hand_angles(Q, geom, mirror=mirror)
    assert np.isnan(res["theta"][[2, 3]]).all() and np.isfinite(np.delete(res["theta"], [2, 3])).all()
    # the faces of a straight tube's notch are parallel, one cut depth long
    faces = hand_angles(to_plane(notch_points(np.zeros(geom.n_joints), geom), 0, 0, 0.3, mirror), geom,
                        mirror=mirror)["faces"][0]
    a, b = (np.subtract(*np.array(f)[::-1]) for f in faces)
    assert abs(a[0] * b[1] - a[1] * b[0]) < 1e-15
    assert np.hypot(*a) == pytest.approx(geom.slot_depths[0])


def test_live_fit_points_at_the_misplaced_corner():
    geom = default_geometry()
    rng = np.random.default_rng(11)
    theta = rng.normal(0.0, 0.03, geom.n_joints)
    Q = to_plane(notch_points(theta, geom), 0.01, 0.02, 0.4) + rng.normal(0, 2e-6, (geom.n_points, 2))
    sig = np.full(geom.n_points, 2e-6)
    good = live_fit(Q, sig, geom)
    assert good["ok"] and 0.3 < good["chi2_dof"] < 3
    Q[20] += (0.05e-3, 0.0)                          # one corner 0.05 mm off
    bad = live_fit(Q, sig, geom)
    res = np.array(bad["residual_mm"])
    assert int(np.argmax(res)) == 20 and bad["chi2_dof"] > 5 * good["chi2_dof"]
    few = live_fit(np.full((geom.n_points, 2), np.nan), sig, geom)
    assert not few["ok"] and "needs more than" in few["message"]


# ----------------------------------------------------------------------------- the session and the fits
def test_edits_are_saved_and_fit_uses_them(study, tmp_path, capsys):
    folder, det, truth = study
    work = work_copy(det, tmp_path)
    with running_server(folder, work) as server:
        s = server.session
        r = s.experiments[0]
        assert s.sample(0, 1)["corners"][BLANKED - 1]["status"] == "occluded"
        u, v = r.uv[0, 20]
        s.edit(0, 1, 21, "move", u=u + 6, v=v, client="a")
        s.edit(0, 1, 30, "delete", client="a")
        true_uv = r.views[0].plane_to_pixel(truth[0, BLANKED - 1])
        out = s.edit(0, 1, BLANKED, "place", u=true_uv[0], v=true_uv[1], client="a")
        assert out["corner"]["status"] == "manual" and out["counts"]["missing"] == 1
        fit = s.fit(0, 1)
    rev = io.read_review(work / "review.csv", n_points=58, sample_ids=[1, 2, 3])
    assert list(rev["point"]) == [BLANKED, 21, 30] and list(rev["status"]) == ["manual", "manual", "deleted"]
    placed = rev.iloc[0]
    # the placed corner lands on the truth (the camera maps the pixel), with a one-pixel sigma
    np.testing.assert_allclose([placed.x_mm, placed.y_mm], truth[0, BLANKED - 1] / MM, atol=2e-4)
    assert placed.sigma_mm == pytest.approx(0.03, rel=0.05) and np.isnan(placed.prev_x_mm)
    assert rev.iloc[1].prev_status == "ok" and rev.iloc[1].prev_u_px == pytest.approx(u)
    assert int(np.nanargmax(np.array(fit["residual_mm"], dtype=float))) == 20
    # fit takes the reviewed points and says so
    assert main(["fit", str(folder), "--points", str(work), "--out", str(tmp_path / "fit"), "--no-figures"]) == 0
    said = capsys.readouterr().out
    assert "detections.csv corrected by review.csv" in said and "(--points, reviewed)" in said
    pw = io.read_pointwise(tmp_path / "fit" / "pointwise.csv")
    free = pw[(pw["model"] == pw["model"].iloc[0]) & (pw["sample"] == 1)].set_index("point")["err_mm"]
    assert free[21] > 0.1 and np.isnan(free[30]) and np.isfinite(free[BLANKED])
    lookup = io.find_points([io.read_experiment(folder)], [("--points", work)])
    assert lookup.sources["exp"] == ("--points, reviewed", work / "review.csv")
    assert np.isnan(lookup.experiments[0].points[0, 29]).all()
    assert source_lines(lookup, "fit") == [f"fit: points of exp from detections.csv corrected by review.csv in "
                                           f"{work} (--points, reviewed)"]
    # each corner's σ: the detector's, and one image pixel (0.03 mm) where corrected by hand
    sig = lookup.experiments[0].point_sigmas / MM
    assert np.isnan(sig[0, 29]) and sig[0, BLANKED - 1] == pytest.approx(placed.sigma_mm)
    d = pd.read_csv(work / "detections.csv").query("sample == 2").set_index("point")["sigma_mm"]
    np.testing.assert_allclose(sig[1], d.sort_index().to_numpy())
    assert io.find_points([io.read_experiment(folder)], [("--points", det)]).experiments[0].point_sigmas is None


def test_two_tabs_last_write_wins_with_a_message(study, tmp_path):
    folder, det, _ = study
    work = work_copy(det, tmp_path)
    with running_server(folder, work) as server:
        s = server.session
        u, v = s.experiments[0].uv[1, 6]
        seen = s.sample(0, 2)["corners"][6]["version"]
        a = s.edit(0, 2, 7, "move", u=u + 2, v=v, version=seen, client="tab-a")
        b = s.edit(0, 2, 7, "move", u=u - 3, v=v, version=seen, client="tab-b")      # b had not seen a's move
        assert a["conflict"] is None and "changed in another tab" in b["conflict"]
        told = s.changes_since(a["seq"], "tab-a")["changes"]
        assert [(c["point"], c["client"]) for c in told] == [(7, "tab-b")]
        assert told[0]["corner"]["u"] == pytest.approx(u - 3)
        assert s.changes_since(0, "tab-b")["changes"][0]["client"] == "tab-a"
        c = s.edit(0, 2, 8, "occlude", version=0, client="tab-a")                  # another corner: no conflict
        assert c["conflict"] is None
        # undo puts back the row the tab saw before; a row that review.csv could not hold is refused
        saved = a["corner"]["review"]
        s.edit(0, 2, 7, "restore", row=saved, client="tab-a")
        assert s.sample(0, 2)["corners"][6]["u"] == pytest.approx(u + 2)
        with pytest.raises(ValueError, match="not a review row"):
            s.edit(0, 2, 7, "restore", row={**saved, "sigma_mm": None})
        s.edit(0, 2, 7, "restore", row=b["corner"]["review"], client="tab-b")
    rev = io.read_review(work / "review.csv")
    assert rev.set_index("point").loc[7, "u_px"] == pytest.approx(u - 3)


def test_accept_an_ambiguous_corner(study, tmp_path):
    """detections.csv keeps an ambiguous corner's pixel only: accepting it maps the pixel to the plane."""
    folder, det, _ = study
    work = tmp_path / "det"
    work.mkdir()
    d = pd.read_csv(det / "detections.csv")
    amb = (d["sample"] == 3) & (d["point"] == 15)
    x_true = d.loc[amb, ["x_mm", "y_mm"]].to_numpy()[0]
    d.loc[amb, ["x_mm", "y_mm", "sigma_mm"]] = np.nan
    d.loc[amb, "status"] = "ambiguous"
    io.write_table_atomic(d, work / "detections.csv")
    with running_server(folder, work) as server:
        s = server.session
        assert s.sample(0, 3)["counts"] == {"ok": 57, "ambiguous": 1, "missing": 0, "manual": 0}
        assert not s.fit(0, 3)["used"][14]                   # shown, not fitted
        out = s.edit(0, 3, 15, "accept")
        assert out["counts"] == {"ok": 58, "ambiguous": 0, "missing": 0, "manual": 1}
        assert s.fit(0, 3)["used"][14]
    row = io.read_review(work / "review.csv").iloc[0]
    np.testing.assert_allclose([row.x_mm, row.y_mm], x_true, atol=1e-9)
    assert row.prev_status == "ambiguous" and row.sigma_mm == pytest.approx(0.03, rel=0.05)


def test_detect_force_keeps_the_review_unless_asked(study, tmp_path, capsys):
    folder, det, _ = study
    out = tmp_path / "det"
    assert main(["detect", str(folder), "--out", str(out), "--no-overlays"]) == 0
    io.write_review([_row()], out / "review.csv")
    before = (out / "review.csv").read_bytes()
    assert main(["detect", str(folder), "--out", str(out), "--no-overlays", "--force"]) == 0
    assert (out / "review.csv").read_bytes() == before
    assert "kept the corrections" in capsys.readouterr().out
    assert main(["detect", str(folder), "--out", str(out), "--no-overlays", "--force", "--drop-review"]) == 0
    assert not (out / "review.csv").exists() and "removed the corrections" in capsys.readouterr().out


# ----------------------------------------------------------------------------- the server is local only
def _request(server, path, *, host=None, origin=None, method="GET", body=None):
    conn = http.client.HTTPConnection("127.0.0.1", server.server_address[1], timeout=10)
    headers = {"Host": host or f"127.0.0.1:{server.server_address[1]}"}
    if origin:
        headers["Origin"] = origin
    if body is not None:
        headers["Content-Type"] = "application/json"
    conn.request(method, path, body=None if body is None else json.dumps(body), headers=headers)
    r = conn.getresponse()
    data = r.read()
    conn.close()
    return r.status, data


def _other_address() -> str | None:
    """An address of this machine that is not the loopback (None when it has none)."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("192.0.2.1", 9))        # no packet is sent: this only picks the outgoing interface
            addr = s.getsockname()[0]
    except OSError:
        return None
    return None if addr.startswith("127.") else addr


def test_server_refuses_other_addresses(study, tmp_path):
    folder, det, _ = study
    with running_server(folder, det) as server:
        port = server.server_address[1]
        assert server.server_address[0] == "127.0.0.1"
        assert _request(server, "/api/study")[0] == 200
        assert _request(server, "/api/study", host=f"localhost:{port}")[0] == 200
        status, data = _request(server, "/api/study", host=f"attacker.example:{port}")
        assert status == 403 and b"is not this server's local address" in data
        status, _ = _request(server, "/api/edit", method="POST", origin="http://attacker.example",
                             body={"exp": 0, "sample": 1, "point": 3, "action": "delete"})
        assert status == 403 and not (det / "review.csv").exists()
        # a request from another machine's address is refused by the handler itself
        a, b = socket.socketpair()
        a.sendall(f"GET /api/study HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n".encode())
        ReviewHandler(b, ("192.0.2.7", 40000), server)
        b.close()
        reply = a.recv(65536).decode()
        a.close()
        assert reply.startswith("HTTP/1.1 403") and "192.0.2.7 is not this machine" in reply
        # nothing listens on the machine's other addresses
        other = _other_address()
        if other is not None:
            with pytest.raises(OSError):
                socket.create_connection((other, port), timeout=2).close()
        status, data = _request(server, "/api/edit", method="POST",
                                body={"exp": 0, "sample": 1, "point": 3, "action": "teleport"})
        assert status == 400 and b"unknown action 'teleport'" in data
        assert _request(server, "/static/../session.py")[0] == 404
        assert _request(server, "/api/sample/0/99")[0] == 404


def test_cli_review_prints_the_address_and_stops_on_ctrl_c(study):
    folder, det, _ = study
    proc = subprocess.Popen([sys.executable, "-m", "notchfit.cli", "review", str(folder), "--points", str(det),
                             "--port", "0"], env=cli_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True).start()
    t0 = time.monotonic()
    while not any("http://127.0.0.1:" in ln for ln in lines):
        assert proc.poll() is None and time.monotonic() - t0 < 60, lines
        time.sleep(0.05)
    url = next(ln for ln in lines if "http://" in ln).split()[2]
    port = int(url.rstrip("/").rsplit(":", 1)[1])
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.request("GET", "/api/study")
    assert conn.getresponse().status == 200
    conn.close()
    proc.send_signal(signal.SIGINT)
    assert proc.wait(20) == 130
    err = proc.stderr.read()
    assert "Traceback" not in err


def test_cli_review_usage_errors(study, tmp_path, capsys):
    folder, det, _ = study
    assert main(["review", str(folder)]) == 2
    assert "give --points DIR" in capsys.readouterr().err
    assert main(["review", str(folder), "--points", str(tmp_path)]) == 2
    assert main(["review", str(folder), "--points", str(det), "--manual-sigma-px", "0"]) == 2
    held = socket.socket()
    held.bind(("127.0.0.1", 0))
    held.listen()
    try:
        assert main(["review", str(folder), "--points", str(det), "--port", str(held.getsockname()[1])]) == 2
        assert "in use" in capsys.readouterr().err
    finally:
        held.close()


def test_the_page_ships_in_the_wheel_and_needs_no_internet():
    """Every file of the page is package data, and none of them loads anything from another site."""
    root = Path(__file__).resolve().parents[1]
    patterns = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    static = sorted((root / "notchfit" / "review" / "static").iterdir())
    assert {p.name for p in static} >= {"index.html", "review.js", "review.css"}
    for p in static:
        rel = p.relative_to(root / "notchfit" / "review").as_posix()
        assert any(Path(rel).match(pat) for pat in patterns["notchfit.review"]), f"{rel} is not package data"
        text = p.read_text(encoding="utf-8")
        assert not re.search(r"(src|href)\s*=\s*[\"'](https?:)?//", text), p.name
        assert not re.search(r"(fetch|import)\s*\(\s*[\"'`]https?:", text), p.name
        assert "@import" not in text and "url(http" not in text, p.name
