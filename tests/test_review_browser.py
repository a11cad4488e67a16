"""``notchfit review`` in a real browser: Playwright driving Chromium (issue 26).

Skipped, with the reason, where Playwright or a Chromium cannot be had (CI installs both: .ci/run).
The browser is Debian's ``chromium`` (/usr/bin/chromium) when present, else Playwright's own.
"""

import os
import shutil

import cv2
import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.cli import main
from notchfit.commands.demo import demo_study
from notchfit.commands.review import study_and_points
from review_helpers import BLANKED, rendered_study, running_server, work_copy

sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright is not installed (pip install playwright); "
                               "the browser tests of notchfit review are skipped")

READY = "window.review && window.review.ready && window.review.fit"


def _executable():
    for path in (os.environ.get("NOTCHFIT_CHROMIUM"), "/usr/bin/chromium", shutil.which("chromium")):
        if path and os.path.isfile(path):
            return path
    return None


@pytest.fixture(scope="module")
def browser():
    try:
        pw = sync_api.sync_playwright().start()
    except Exception as exc:  # noqa: BLE001 - any start-up failure means: no browser here
        pytest.skip(f"Playwright cannot start ({exc}); the browser tests of notchfit review are skipped")
    try:
        b = pw.chromium.launch(executable_path=_executable(), args=["--no-sandbox"])
    except Exception as exc:  # noqa: BLE001
        pw.stop()
        pytest.skip(f"no Chromium to drive (apt-get install chromium, or playwright install chromium): "
                    f"{str(exc).splitlines()[0]}")
    yield b
    b.close()
    pw.stop()


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    return rendered_study(tmp_path_factory.mktemp("review_browser"))


def _open(browser, url):
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    page.wait_for_function(READY, timeout=30000)
    return page, errors


def _screen(page, u, v):
    """Page coordinates of image pixel (u, v)."""
    box = page.locator("#canvas").bounding_box()
    x, y = page.evaluate("([u, v]) => window.review.toScreen(u, v)", [u, v])
    return box["x"] + x, box["y"] + y


def _corner(page, point):
    return page.evaluate(f"window.review.data.corners[{point - 1}]")


def _drag(page, point, du_px, dv_px):
    c = _corner(page, point)
    x0, y0 = _screen(page, c["u"], c["v"])
    page.mouse.move(x0, y0)
    page.mouse.down()
    page.mouse.move(x0 + du_px / 2, y0 + dv_px / 2, steps=3)
    page.mouse.move(x0 + du_px, y0 + dv_px, steps=3)
    page.mouse.up()


def _wait_message(page, text):
    try:
        page.wait_for_function("t => document.getElementById('message').textContent.includes(t)", arg=text,
                               timeout=10000)
    except sync_api.TimeoutError:
        raise AssertionError(f"waited for {text!r}; the page says {page.inner_text('#message')!r}") from None


def _click_corner(page, point):
    c = _corner(page, point)
    page.mouse.click(*_screen(page, c["u"], c["v"]))


def test_correct_a_sample_then_fit_uses_it(browser, study, tmp_path, capsys):
    folder, det, truth = study
    work = work_copy(det, tmp_path)
    with running_server(folder, work) as server:
        page, errors = _open(browser, server.url)
        assert page.locator(".thumb").count() == 3
        assert page.locator(".thumb.current .c-miss").inner_text() == "1"
        start = _corner(page, 21)
        _drag(page, 21, 24, 0)                                           # move corner 21
        _wait_message(page, "corner 21: move")
        page.keyboard.press("m")                                          # the next missing corner: BLANKED
        assert page.evaluate("window.review.selected") == BLANKED
        u, v = server.session.experiments[0].views[0].plane_to_pixel(truth[0, BLANKED - 1])
        page.mouse.move(*_screen(page, u, v))
        for _ in range(3):                                                # zoom in there, as a person would
            page.mouse.wheel(0, -300)
        page.wait_for_function("window.review.view.scale > 2")
        page.mouse.click(*_screen(page, u, v))                            # place it
        _wait_message(page, f"corner {BLANKED}: place")
        page.keyboard.press("f")                                          # back to the whole photograph
        _click_corner(page, 30)
        page.keyboard.press("Delete")                                     # delete corner 30
        _wait_message(page, "corner 30: delete")
        _drag(page, 40, 0, 30)
        _wait_message(page, "corner 40: move")
        page.keyboard.press("z")                                          # undo the move of 40
        _wait_message(page, "undone: corner 40")
        page.reload()
        page.wait_for_function(READY, timeout=30000)
        c21, placed, c30, c40 = (_corner(page, q) for q in (21, BLANKED, 30, 40))
        assert c21["status"] == "manual" and c21["u"] > start["u"] + 10
        assert placed["status"] == "manual" and abs(placed["u"] - u) < 1.5 and abs(placed["v"] - v) < 1.5
        assert c30["status"] == "deleted" and c30["u"] is None
        assert c40["status"] == "ok" and not c40["corrected"]
        assert page.locator(".thumb.current .c-miss").inner_text() == "1"      # 30 missing, BLANKED placed
        resid = page.evaluate("window.review.fit.residual_mm")
        assert int(np.nanargmax(np.array(resid, dtype=float))) == 20         # the fit points at corner 21
        page.keyboard.press("g")                                          # angles by hand
        page.wait_for_function("window.review.angles && window.review.angles.theta_deg.length === 27")
        assert page.locator("#angles-table tbody tr").count() == 27
        page.click("#b-write-angles")
        page.wait_for_function("document.getElementById('angles-note').textContent.includes('written')")
        assert not errors, errors
        page.close()
    angles = io.read_angles_table(work / "angles.csv", n_joints=27, sample_ids=[1, 2, 3])
    theta = angles.pivot(index="sample", columns="joint", values="theta")
    np.testing.assert_allclose(theta.loc[3], 0.04, atol=5e-4)      # sample 3 was rendered at θ = 0.04 rad
    assert theta.loc[1].notna().all()                  # every link keeps two corners (30 deleted, 10 placed)
    rev = io.read_review(work / "review.csv")
    assert sorted(rev["point"]) == sorted([21, BLANKED, 30])
    # fit uses the corrections: corner 21's residual grows, 30 is gone, the placed corner is fitted
    args = ["fit", str(folder), "--out", str(tmp_path / "fit_{}"), "--no-figures", "--models", "free"]
    assert main([a.format("reviewed") for a in args] + ["--points", str(work)]) == 0
    assert "corrected by review.csv" in capsys.readouterr().out
    assert main([a.format("detected") for a in args] + ["--points", str(det)]) == 0
    errs = {k: io.read_pointwise(tmp_path / f"fit_{k}" / "pointwise.csv").query("sample == 1").set_index("point")
            ["err_mm"] for k in ("reviewed", "detected")}
    print(f"\ncorner 21 residual: detected {errs['detected'][21] * 1e3:.1f} µm, moved by hand "
          f"{errs['reviewed'][21] * 1e3:.1f} µm")
    assert errs["reviewed"][21] > 10 * errs["detected"][21] and errs["reviewed"][21] > 0.2
    assert np.isnan(errs["reviewed"][30]) and np.isfinite(errs["reviewed"][BLANKED])
    assert np.isnan(errs["detected"][BLANKED])


def test_two_tabs_keep_each_others_edits(browser, study, tmp_path):
    folder, det, _ = study
    work = work_copy(det, tmp_path)
    with running_server(folder, work) as server:
        a, errs_a = _open(browser, server.url)
        b, errs_b = _open(browser, server.url)
        b.evaluate("window.review.pollPaused = true")   # tab b does not hear of a's change in time
        _drag(a, 7, 12, 0)                              # tab a moves corner 7
        _wait_message(a, "corner 7: move")
        _drag(b, 7, -12, 0)                             # tab b, which had not seen it, moves it too
        _wait_message(b, "changed in another tab; your change replaced it")
        b.evaluate("window.review.pollPaused = false")
        _wait_message(a, "corner 7 of sample 1 was changed in another tab")
        _drag(a, 12, 0, 12)                             # a different corner: both kept
        _wait_message(a, "corner 12: move")
        _wait_message(b, "corner 12 of sample 1 was changed in another tab")
        ua, ub = (p.evaluate("window.review.data.corners[6].u") for p in (a, b))
        assert ua == pytest.approx(ub)
        # worst first: sample 3 with two corners gone heads the strip
        a.keyboard.press("n")
        a.wait_for_function("window.review.ready && window.review.sample === 2")
        a.keyboard.press("ArrowRight")
        a.wait_for_function("window.review.ready && window.review.sample === 3")
        for q, key in ((5, "Delete"), (6, "o")):
            _click_corner(a, q)
            a.keyboard.press(key)
            _wait_message(a, f"corner {q}: {'delete' if q == 5 else 'occlude'}")
        assert a.locator(".thumb").first.get_attribute("data-sample") == "1"
        a.check("#worst")
        assert a.locator(".thumb").first.get_attribute("data-sample") == "3"
        assert a.locator(".thumb.current .c-miss").inner_text() == "2"
        assert not errs_a and not errs_b
        a.close()
        b.close()
    rev = io.read_review(work / "review.csv")
    assert list(zip(rev["sample"], rev["point"], rev["status"])) == [
        (1, 7, "manual"), (1, 12, "manual"), (3, 5, "deleted"), (3, 6, "occluded")]
    assert rev.iloc[0]["u_px"] == pytest.approx(ua)


def _big_study(root, study, size=(4928, 3264)):
    """The rendered study's photographs blown up to 16 Mpx JPEG files (a camera's size), its detections
    scaled with them; no camera file (the diameter scale)."""
    folder, det, _ = study
    big = root / "big"
    (big / "images").mkdir(parents=True)
    samples = pd.read_csv(folder / "samples.csv")
    f = None
    for name in samples["image"]:
        img = cv2.imread(str(folder / name), cv2.IMREAD_UNCHANGED)
        f = (size[0] / img.shape[1], size[1] / img.shape[0])
        cv2.imwrite(str(big / name).replace(".png", ".jpg"), cv2.resize(img, size, interpolation=cv2.INTER_CUBIC),
                    [cv2.IMWRITE_JPEG_QUALITY, 92])
    samples["image"] = samples["image"].str.replace(".png", ".jpg")
    samples.to_csv(big / "samples.csv", index=False)
    (big / "experiment.toml").write_text('name = "big"\ngeometry = "default"\n')
    d = pd.read_csv(det / "detections.csv")
    d["u_px"], d["v_px"] = (d["u_px"] + 0.5) * f[0] - 0.5, (d["v_px"] + 0.5) * f[1] - 0.5
    (root / "bigdet").mkdir()
    d.to_csv(root / "bigdet" / "detections.csv", index=False)
    return big, root / "bigdet"


def test_page_load_and_image_switch_on_16_mp_photographs(browser, study, tmp_path):
    """The figures the issue asks for (under 1 s each on 2 cores): printed, not asserted tightly."""
    big, det = _big_study(tmp_path, study)
    with running_server(big, det) as server:
        page, errors = _open(browser, server.url)
        first = page.evaluate("window.review.timings[0]")
        info = page.evaluate("window.review.data.image")
        assert (info["width"], info["height"]) == (4928, 3264) and len(info["levels"]) == 5
        switches = []
        for key, sample in (("n", 2), ("n", 3), ("p", 2)):
            page.keyboard.press(key)
            page.wait_for_function(f"window.review.ready && window.review.sample === {sample}", timeout=30000)
            switches.append(page.evaluate("window.review.timings.at(-1).ms"))
        # zoom to full resolution at the tube: only the tiles in view are fetched
        box = page.locator("#canvas").bounding_box()
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        for _ in range(8):
            page.mouse.wheel(0, -400)
        page.wait_for_function("window.review.view.scale >= 1")
        tiles = page.evaluate("window.review.tiles.size")
        assert not errors, errors
        page.close()
    print(f"\n16 Mpx photograph ({info['width']}x{info['height']} JPEG): page load {first['at']:.0f} ms "
          f"(image and corners drawn {first['ms']:.0f} ms after the first request); image switch "
          + ", ".join(f"{s:.0f}" for s in switches) + f" ms; {tiles} tiles fetched in all")
    assert first["at"] < 10000 and max(switches) < 10000          # generous: the figures are the result


@pytest.mark.slow
def test_review_the_demo_study(browser, tmp_path, capsys):
    """The demo's study of photographs (small: 4 experiments, 76 images), reviewed from its detect folder
    alone (detect_run.json names the study): every experiment listed, a corner moved, fit uses it."""
    demo_study(tmp_path / "study", small=True, images=True)
    assert main(["detect", str(tmp_path / "study"), "--out", str(tmp_path / "results"), "--no-overlays"]) in (0, 1)
    study, points = study_and_points(tmp_path / "results")
    assert study == (tmp_path / "study").resolve() and points == tmp_path / "results"
    with running_server(study, points) as server:
        names = [r.exp.name for r in server.session.experiments]
        page, errors = _open(browser, server.url)
        assert page.locator("#exp option").count() == len(names) == 4
        page.select_option("#exp", "1")
        page.wait_for_function("window.review.ready && window.review.exp === 1 && window.review.fit")
        n = page.evaluate("window.review.study.experiments[1].samples.length")
        assert page.locator(".thumb").count() == n
        sample = page.evaluate("window.review.sample")
        _drag(page, 40, 20, 0)
        _wait_message(page, "corner 40: move")
        page.reload()
        page.wait_for_function(READY, timeout=30000)
        page.select_option("#exp", "1")
        page.wait_for_function("window.review.ready && window.review.exp === 1")
        assert _corner(page, 40)["status"] == "manual"
        assert not errors, errors
        page.close()
    capsys.readouterr()
    assert main(["fit", str(study / names[1]), "--points", str(points), "--out", str(tmp_path / "fit"),
                 "--no-figures", "--models", "free"]) == 0
    assert f"points of {names[1]} from detections.csv corrected by review.csv" in capsys.readouterr().out
    err = io.read_pointwise(tmp_path / "fit" / "pointwise.csv").query(f"sample == {sample}").set_index("point")
    assert err.loc[40, "err_mm"] > 0.3
