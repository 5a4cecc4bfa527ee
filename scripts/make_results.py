#!/usr/bin/env python3
"""Writes docs/results.md and its plots (docs/results/*.svg) from the measurements in docs/results/*.json
and the device checks in docs/device/*.json. Python 3 standard library only.

    python3 scripts/make_results.py            regenerate docs/results.md and docs/results/*.svg
    python3 scripts/make_results.py --out DIR  write DIR/results.md and DIR/results/*.svg instead
    python3 scripts/make_results.py --check    regenerate into a temporary folder and diff against the
                                               committed files (CTest results_page); exit 1 on a difference

Every number on the page comes from a record; each record carries its command, the commit it was built at
(`commit`, where the run named it), the commit that first recorded it (`recorded_in`: the first commit whose
README.md, docs/results.md or docs/experiments.md held the run's sentence, found with `git log -S`), the
machine (ids described in each file's `machines`), and its numbers, whose units are in the file's `fields`. Numbers are printed exactly as written in the data
(0.410 stays 0.410). The best rows at the top are chosen from the records by the rules in best_stages().
"""
import argparse
import difflib
import json
import os
import sys
import tempfile
from decimal import Decimal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import results_plots as plots  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COMMAND = "python3 scripts/make_results.py"
SCENE_ORDER = ["lego", "fern", "horns", "milk_carton", "bird_figurine", "demo"]
SCENE_NAME = {"lego": "lego", "fern": "fern", "horns": "horns", "milk_carton": "milk_carton",
              "bird_figurine": "bird_figurine", "demo": "the demo scene"}
MACHINE_SHORT = {"cpu2": "2-core CPU", "cpu2-xeon": "2-core Xeon", "cpu2-epyc": "2-core EPYC", "h100": "H100",
                 "h200": "H200"}
SVGS = ["density.svg", "features.svg", "style.svg", "consistency_rays.svg", "consistency_time.svg",
        "resolution.svg", "gpu.svg"]


# --- data ------------------------------------------------------------------------------------------------

def load(root, name):
    with open(os.path.join(root, name)) as f:
        return json.load(f, parse_float=Decimal)


def num(rec, key):
    return rec["numbers"].get(key)


def text(v):
    """A number as written in the data."""
    return str(v)


def pixels(resolution):
    w, h = resolution.split("x")
    return int(w) * int(h)


def sort_key(rec):
    return (SCENE_ORDER.index(rec["scene"]), -pixels(rec["resolution"]), float(num(rec, "minutes") or 0), rec["id"])


def commit_cell(rec):
    if rec.get("commit"):
        return "`%s`" % rec["commit"]
    return "*%s*" % rec["recorded_in"]


def _code(part):
    """One command as code, a trailing parenthetical left as prose."""
    tail = ""
    if part.endswith(")") and " (" in part:
        i = part.rfind(" (")
        part, tail = part[:i], part[i:]
    return "`%s`%s" % (part.replace("|", "\\|"), tail.replace("|", "\\|"))


def cmd_cell(command):
    """Commands as code: prose before the first command stays prose, '; ' separates commands."""
    starts = [i for i in (command.find(t) for t in ("stylerf ", "bash ", "python3 ")) if i >= 0]
    i = min(starts) if starts else 0
    return command[:i] + ", then ".join(_code(p) for p in command[i:].split("; "))


def cell(v, unit="", none="—"):
    return none if v is None else text(v) + unit


def pair(a, b, unit="x"):
    if a is None and b is None:
        return "—"
    return "%s / %s" % (cell(a, unit), cell(b, unit))


def table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


def scene_size(rec):
    return "%s %s" % (SCENE_NAME[rec["scene"]], rec["resolution"])


def is_default(rec):
    return "(default)" in rec.get("variant", "")


# --- the top of the page -----------------------------------------------------------------------------------

def run_rows(runs):
    rows = []
    for r in sorted((r for r in runs if r.get("top")), key=sort_key):
        n = r["numbers"]
        frame = (cell(n.get("frame_s"), " s") if n.get("frame_s") is not None else
                 "%s + %s s (plan)" % (text(n["probe_content_s"]), text(n["probe_style_s"])) if
                 n.get("probe_content_s") is not None else "—")
        style = "**%s** (worst %s)" % (cell(n.get("style_ratio_x"), "x"), cell(n.get("style_worst_x"), "x"))
        rows.append([
            "<a id=\"%s\"></a>**%s**" % (r["anchor"], scene_size(r)),
            cell(n.get("total_min"), " min"), cell(n.get("density_psnr_db"), " dB"),
            cell(n.get("decoded_psnr_db"), " dB"), style,
            pair(n.get("content_ratio_x"), n.get("structure_lpips_x")),
            pair(n.get("short_rmse_x"), n.get("long_rmse_x")),
            pair(n.get("short_lpips_x"), n.get("long_lpips_x")) + (" (%s)" % LPIPS_NET[r["lpips_net"]]),
            frame, cell(n.get("peak_rss_gb"), " GB"), MACHINE_SHORT[r["machine"]] + ", " + r["date"],
            commit_cell(r), cmd_cell(r["command"])])
    return rows


LPIPS_NET = {"alex": "AlexNet", "vgg16": "VGG-16"}


def demo_rows(demo, top_only):
    rows = []
    for r in sorted(demo, key=lambda r: (r["machine"], r["cache"] != "warm", r["id"])):
        if top_only and not r.get("top"):
            continue
        n = r["numbers"]
        first = ("<a id=\"%s\"></a>**%s**" % (r["anchor"], MACHINE_SHORT[r["machine"]])) if r.get("anchor") and top_only \
            else MACHINE_SHORT[r["machine"]]
        rows.append([first, r["cache"], cell(n["seconds"], " s"), cell(n["density_psnr_db"], " dB"),
                     cell(n["decoded_psnr_db"], " dB"),
                     "%s (worst %s)" % (cell(n["style_ratio_x"], "x"), cell(n["style_worst_x"], "x")),
                     cell(n["short_rmse_x"], "x"), cell(n["short_lpips_x"], "x") + " (AlexNet)",
                     cell(n["mix_corners"]), r.get("date", r["recorded_on"]), commit_cell(r)])
    return rows


def style_candidates(style, runs):
    """Style-stage records: train-style alone, and the style stage of each stylerf run."""
    out = [dict(r, how="train-style alone: " + r["variant"]) for r in style]
    for r in runs:
        n = r["numbers"]
        if n.get("style_ratio_x") is None or n.get("style_min") is None:
            continue
        numbers = {"minutes": n["style_min"], "steps": n.get("style_steps"), "style_ratio_x": n["style_ratio_x"],
                   "style_worst_x": n.get("style_worst_x"), "content_ratio_x": n.get("content_ratio_x"),
                   "short_rmse_x": n.get("short_rmse_x"), "long_rmse_x": n.get("long_rmse_x"),
                   "views": n.get("style_views"), "styles": n.get("style_styles")}
        out.append(dict(r, numbers={k: v for k, v in numbers.items() if v is not None},
                        how="the style stage of stylerf run: " + r["recipe"],
                        command="the style stage of " + r["command"]))
    return out


def best_stages(density, features, style_all):
    """The best CPU record of each stage per scene and size: the highest PSNR, the lowest style ratio."""
    rows = []

    def best(records, key, lower):
        groups = {}
        for r in records:
            if not r["machine"].startswith("cpu") or num(r, key) is None:
                continue
            groups.setdefault((r["scene"], r["resolution"]), []).append(r)
        picked = []
        for g in groups.values():
            g.sort(key=lambda r: ((num(r, key) if lower else -num(r, key)), r["id"]))
            picked.append(g[0])
        return sorted(picked, key=lambda r: (SCENE_ORDER.index(r["scene"]), -pixels(r["resolution"])))

    for stage, records, key, lower in (("density", density, "psnr_db", False),
                                       ("features", features, "psnr_db", False),
                                       ("style", style_all, "style_ratio_x", True)):
        for r in best(records, key, lower):
            n = r["numbers"]
            anchor = "%s-%s-%s" % (stage, r["scene"].replace("_", "-"), r["resolution"].split("x")[0])
            if stage == "style":
                result = "**%sx** 2D AdaIN's style loss" % text(n["style_ratio_x"])
                if n.get("style_worst_x") is not None:
                    result += " (worst %sx)" % text(n["style_worst_x"])
                how = r["how"]
            else:
                result = "**%s dB**" % text(n["psnr_db"])
                extra = [x for x in (("SSIM " + text(n["ssim"])) if n.get("ssim") is not None else None,
                                     ("%s views" % n["views"]) if n.get("views") is not None else None) if x]
                if extra:
                    result += " (" + ", ".join(extra) + ")"
                how = r["variant"]
            rows.append(["<a id=\"%s\"></a>%s" % (anchor, stage), scene_size(r), result, cell(n["minutes"], " min"),
                         how, MACHINE_SHORT[r["machine"]], commit_cell(r), cmd_cell(r["command"])])
    return rows


# --- plots -------------------------------------------------------------------------------------------------

def series_by(records, key_of, x_key, y_key, hollow_of=None, label_of=None, line=False):
    groups = {}
    for r in sorted(records, key=sort_key):
        x, y = num(r, x_key) if isinstance(x_key, str) else x_key(r), num(r, y_key)
        if x is None or y is None:
            continue
        pt = {"x": float(x), "y": float(y)}
        if hollow_of and hollow_of(r):
            pt["hollow"] = True
        if label_of:
            pt["label"] = label_of(r)
        groups.setdefault(key_of(r), []).append(pt)
    return [{"name": k, "points": v, "line": line} for k, v in groups.items()]


HOLLOW_NOT_DEFAULT = ("hollow: a setting that is not the default now", "#555", "circle", True, False)


def plot_density(density):
    def key(r):
        if r["machine"].startswith("h"):
            return "lego 800x800 on a GPU (H100, H200)"
        return scene_size(r)
    series = series_by(density, key, "minutes", "psnr_db", hollow_of=lambda r: not is_default(r))
    for s in series:
        if s["name"].endswith("GPU (H100, H200)"):
            s["marker"], s["colour"] = "cross", "#000000"
    return plots.scatter("Density stage: held-out PSNR against its minutes", "minutes of the density stage",
                         "held-out PSNR (dB)", series, [HOLLOW_NOT_DEFAULT], x_include=[0])


def plot_features(features):
    series = series_by(features, scene_size, "minutes", "psnr_db", hollow_of=lambda r: not is_default(r))
    return plots.scatter("Feature stage: decoded held-out PSNR against its minutes",
                         "minutes of the feature stage", "decoded held-out PSNR (dB)", series,
                         [("hollow: the pixels + VGG patch loss (the default until 2026-12-02)", "#555", "circle",
                           True, False)], x_include=[0])


def plot_style(style_all):
    series = series_by(style_all, scene_size, "minutes", "style_ratio_x",
                       hollow_of=lambda r: r["how"].startswith("train-style alone"))
    return plots.scatter("Held-out style loss against the style stage's minutes", "minutes of the style stage",
                         "held-out style loss / 2D AdaIN's", series,
                         [("filled: stylerf run's style stage; hollow: train-style alone", "#555", "circle", True,
                           False)], x_include=[0], y_refs=[(1.0, "as 2D AdaIN")])


RAYS = ["1", "quincunx", "2x2", "3x3"]


def plot_consistency_rays(cons):
    recs = [r for r in cons if "exact" not in r["model"] and "slab" not in r["model"]]
    series = series_by(recs, lambda r: r["model"], lambda r: RAYS.index(r["rays"]), "short_rmse_x", line=True)
    return plots.scatter("Short-range consistency against content rays per 4x4 feature block",
                         "content rays per block (quincunx: the centre and 4 shared corners)",
                         "short-range RMSE / per-frame AdaIN's", series, x_categories=RAYS,
                         y_refs=[(1.0, "as per-frame 2D AdaIN")])


def plot_consistency_time(cons):
    def label(r):
        extra = " exact" if "exact" in r["model"] else " per slab" if "slab" in r["model"] else ""
        return r["rays"] + extra
    recs = [r for r in cons if num(r, "content_s") is not None]
    series = series_by(recs, lambda r: r["model"].replace(", 3x3 averaged exactly", "").replace(
        ", 3x3 shaded per depth slab (default)", ""), "content_s", "short_rmse_x", label_of=label, line=True)
    return plots.scatter("Short-range consistency against the content render's time",
                         "content render of one view (s, log scale)", "short-range RMSE / per-frame AdaIN's",
                         series, x_log=True, y_include=[0.6])


def plot_resolution(runs):
    recs = [r for r in runs if r.get("top") and r["scene"] in ("lego", "fern")]
    key = lambda r: SCENE_NAME[r["scene"]]
    mp = lambda r: pixels(r["resolution"]) / 1e6
    frame = lambda r: (float(num(r, "probe_content_s")) + float(num(r, "probe_style_s")))
    psnr = series_by(recs, key, mp, "decoded_psnr_db", line=True)
    style = series_by(recs, key, mp, "style_ratio_x", line=True)
    groups = {}
    for r in sorted(recs, key=sort_key):
        groups.setdefault(key(r), []).append({"x": mp(r), "y": frame(r)})
    frames = [{"name": k, "points": v, "line": True} for k, v in groups.items()]
    common = dict(x_label="megapixels a view (log scale)", x_log=True)
    return plots.panels("stylerf run --minutes 90 at each resolution: quality and frame time", [
        dict(common, subtitle="decoded held-out views", y_label="PSNR (dB)", series=psnr),
        dict(common, subtitle="held-out style", y_label="style loss / 2D AdaIN's", series=style,
             y_refs=[(1.0, "as 2D AdaIN")]),
        dict(common, subtitle="a stylised frame (the run's plan)", y_label="content + one style (s, log scale)",
             series=frames, y_log=True)], panel_w=250, panel_h=240)


def gpu_step(root, path, part):
    d = load(root, path)
    return d["parts"][part]["step_s"], d


def plot_gpu(root, gpu):
    groups = []
    for r in gpu:
        h100, _ = gpu_step(root, r["gpu"][0], r["gpu"][1])
        h200, _ = gpu_step(root, "docs/device/h200_device_check.json", r["gpu"][1])
        groups.append((r["what"], [float(num(r, "cpu_s")), float(h100), float(h200)]))
    return plots.bars("One training step: the 2-core CPU against one GPU", "seconds a step (log scale)", groups,
                      ["2-core CPU (PoCL)", "NVIDIA H100", "NVIDIA H200"])


# --- the page ----------------------------------------------------------------------------------------------

def sec3(v):
    return "%.3f" % float(v)


def page(root):
    runs = load(root, "docs/results/runs.json")["records"]
    demo = load(root, "docs/results/demo.json")["records"]
    density = load(root, "docs/results/density.json")["records"]
    features = load(root, "docs/results/features.json")["records"]
    style = load(root, "docs/results/style.json")["records"]
    cons = load(root, "docs/results/consistency.json")["records"]
    gpu = load(root, "docs/results/gpu.json")["records"]
    knobs = load(root, "docs/results/knobs.json")["records"]
    viewer = load(root, "docs/results/viewer.json")["records"]
    mpi = load(root, "docs/results/mpi.json")
    machines = load(root, "docs/results/runs.json")["machines"]
    style_all = style_candidates(style, runs)
    h100 = load(root, "docs/device/h100_device_check.json")
    h200 = load(root, "docs/device/h200_device_check.json")

    svgs = {"density.svg": plot_density(density), "features.svg": plot_features(features),
            "style.svg": plot_style(style_all), "consistency_rays.svg": plot_consistency_rays(cons),
            "consistency_time.svg": plot_consistency_time(cons), "resolution.svg": plot_resolution(runs),
            "gpu.svg": plot_gpu(root, gpu)}

    L = ["*Generated by `%s` from docs/results/*.json and docs/device/*.json: edit the data, then rerun it "
         "(CTest `results_page` fails when this page or a plot differs from what the data gives).*" % COMMAND, "",
         "# Results: what each stage reaches, and what accuracy costs in time", "",
         "Each figure is one measured run, with the command that made it. A commit in `code` is the build the run "
         "names; one in *italics* is the commit that first recorded the number, where the run named no build. "
         "Machines are listed at the end; a 2-core EPYC host ran this code 2-3x faster than the 2-core Xeon, so "
         "compare minutes only on one machine.", "",
         "How to read the ratios:",
         "- **style loss / 2D AdaIN**: `stylerf eval-style`'s style loss of our stylised test views under held-out "
         "styles (never trained on), divided by 2D AdaIN's on the true views, by the same VGG and opacity mask. "
         "Below 1 is closer to the style than 2D AdaIN;",
         "- **content loss, LPIPS to the truth / 2D AdaIN**: the same evaluation's content loss, and LPIPS between "
         "the true view and the stylised one (a structure score training never sees), each over 2D AdaIN's. "
         "Below 1 keeps the object's structure better than 2D AdaIN. A style ratio is good only beside these two;",
         "- **short / long RMSE, LPIPS**: `stylerf eval table`'s consistency of StyleRF's frames along the camera "
         "path, divided by per-frame 2D AdaIN's (below 1 is steadier; the paper reports 0.67x / 0.74x RMSE).", ""]

    L += ["## `stylerf run`: the whole pipeline in one command", "",
          "The default (fast) recipe, `--minutes 90` unless the command says otherwise, each run alone on its "
          "machine. *Frame*: a stylised frame at the run's resolution, measured with `stylerf stylize`, or the "
          "run's own plan (the content of one frame + one style) where no frame was timed.", ""]
    L += table(["scene, size", "time", "density", "decoded", "style loss / 2D AdaIN",
                "content loss / LPIPS to the truth, over 2D AdaIN's", "short / long RMSE",
                "short / long LPIPS", "frame", "peak RSS", "machine, date", "commit", "command"], run_rows(runs))
    L += ["", "The built-in demo (`bash scripts/demo.sh`: a generated 128 px scene, 32 generated styles of which "
          "4 are held out; by iteration counts, so its ratios do not depend on the machine's speed):", ""]
    L += table(["machine", "PoCL cache", "time", "density", "decoded", "style loss / 2D AdaIN",
                "short RMSE", "short LPIPS", "mix corners", "date", "commit"], demo_rows(demo, True))
    L += ["", "### Each stage alone: the best measured", "",
          "Chosen from the records below: the highest held-out PSNR of each scene and size for the density and "
          "feature stages, the lowest held-out style loss for the style stage (`stylerf run`'s style stage "
          "included). CPU runs only; the GPU is further down.", ""]
    L += table(["stage", "scene, size", "result", "minutes", "how", "machine", "commit", "command"],
               best_stages(density, features, style_all))
    proj = h100["projection"]
    L += ["", "<a id=\"gpu-h100\"></a>On an **%s** (commit `%s`, %s): the paper's schedule (density 30k, "
          "features 25k, style 25k steps) projects to **%.2f h**; a style step of the paper profile takes %s s, "
          "of the fast profile %s s; tests %d pass, %d fail (more in [The GPU](#the-gpu))." % (
              h100["device"], h100["git_commit"][:7], h100["date"][:10], proj["total_hours"],
              sec3(h100["parts"]["patch_s3_paper"]["step_s"]), sec3(h100["parts"]["patch_s3_fast"]["step_s"]),
              h100["parts"]["tests"]["passed"], h100["parts"]["tests"]["failed"]), ""]

    L += density_section(density) + feature_section(features) + style_section(style_all)
    L += consistency_section(cons) + resolution_section(runs) + budget_section(runs) + demo_section(demo)
    L += viewer_section(viewer) + mpi_section(mpi, h100)
    L += knobs_section(knobs) + gpu_section(gpu, h100, h200, root) + machines_section(machines)
    return "\n".join(L) + "\n", svgs


def by_id(records, rid):
    return next(r for r in records if r["id"] == rid)


def said(records, rid, key, unit=""):
    return text(num(by_id(records, rid), key)) + unit


def density_section(density):
    d = lambda rid, key, unit="": said(density, rid, key, unit)
    L = ["## Density stage: PSNR against minutes", "", "![Density PSNR against minutes](results/density.svg)", "",
         "Deferred shading (the default) is what makes the first minutes count: lego 200x200 reaches %s in %s, "
         "where TensoRF's per-sample shading had %s after %s. An H100 reaches %s at 800x800 in %s; a 2-core "
         "CPU %s in %s." % (
             d("density-lego-200-10min", "psnr_db", " dB"), d("density-lego-200-10min", "minutes", " minutes"),
             d("density-lego-200-bench-30", "psnr_db", " dB"), d("density-lego-200-bench-30", "minutes", ""),
             d("density-lego-800-h100", "psnr_db", " dB"), d("density-lego-800-h100", "minutes", " minutes"),
             d("density-lego-800-10min", "psnr_db", " dB"), d("density-lego-800-10min", "minutes", "")), ""]
    rows = [[scene_size(r), r["variant"], cell(num(r, "minutes"), " min"), cell(num(r, "psnr_db"), " dB"),
             cell(num(r, "ssim")), cell(num(r, "views")), cell(num(r, "steps")), MACHINE_SHORT[r["machine"]],
             commit_cell(r), cmd_cell(r["command"])] for r in sorted(density, key=sort_key)]
    return L + table(["scene, size", "setting", "minutes", "PSNR", "SSIM", "views", "steps", "machine", "commit",
                      "command"], rows) + [""]


def feature_section(features):
    L = ["## Feature stage: decoded PSNR against minutes", "",
         "![Decoded PSNR against minutes](results/features.svg)", "",
         "The patch loss of pixels alone (`--content-weight 0`, the default) decodes fern 1008x756 at %s against "
         "%s for the pixels + VGG loss, on the same density checkpoint and minutes, and lego 800x800 at %s. The "
         "fast profile renders features at 1/4 of the view, so smaller views decode lower." % (
             said(features, "features-fern-1008-30min", "psnr_db", " dB"),
             said(features, "features-fern-1008-30min-vgg", "psnr_db", " dB"),
             said(features, "features-lego-800-30min", "psnr_db", " dB")), ""]
    rows = [[scene_size(r), r["variant"], cell(num(r, "minutes"), " min"), cell(num(r, "psnr_db"), " dB"),
             cell(num(r, "ssim")), cell(num(r, "views")), cell(num(r, "steps")), MACHINE_SHORT[r["machine"]],
             commit_cell(r), cmd_cell(r["command"])] for r in sorted(features, key=sort_key)]
    return L + table(["scene, size", "patch loss", "minutes", "decoded PSNR", "SSIM", "views", "steps", "machine",
                      "commit", "command"], rows) + [""]


def style_section(style_all):
    L = ["## Style stage: held-out style loss against minutes", "",
         "![Held-out style loss against the style stage's minutes](results/style.svg)", "",
         "Minutes are not the whole story: the same minutes buy 2-3x the steps on the faster host, and two "
         "seeds of one recipe can differ by a quarter of AdaIN's loss (docs/experiments.md). Lego's ratio is masked by the rendered opacity, where 2D AdaIN "
         "paints the whole square, so it sits lower than the forward-facing scenes'.", ""]
    lego = sorted((r for r in style_all if r["scene"] == "lego" and r["resolution"] == "200x200"),
                  key=lambda r: (num(r, "style_ratio_x"), r["id"]))
    if lego:
        lo, hi = lego[0], lego[-1]
        L += ["On lego 200x200 the records range from **%sx** (%s; %s min, %s steps, %s, commit %s) to %sx (%s; "
              "%s min, %s steps, %s, commit %s): a different recipe and build, each row with its command." % (
                  text(num(lo, "style_ratio_x")), lo["how"], text(num(lo, "minutes")), cell(num(lo, "steps")),
                  MACHINE_SHORT[lo["machine"]], commit_cell(lo), text(num(hi, "style_ratio_x")), hi["how"],
                  text(num(hi, "minutes")), cell(num(hi, "steps")), MACHINE_SHORT[hi["machine"]], commit_cell(hi))]
        if all(num(r, "views") is not None and num(r, "styles") is not None for r in (lo, hi)) and \
                (num(lo, "views"), num(lo, "styles")) == (num(hi, "views"), num(hi, "styles")):
            L[-1] += " Both score %s held-out styles on %s test views." % (num(lo, "styles"), num(lo, "views"))
        L += [""]
    rows = [[scene_size(r), r["how"], cell(num(r, "minutes"), " min"), cell(num(r, "steps")),
             "%s (worst %s)" % (cell(num(r, "style_ratio_x"), "x"), cell(num(r, "style_worst_x"), "x")),
             cell(num(r, "content_ratio_x"), "x"), pair(num(r, "short_rmse_x"), num(r, "long_rmse_x")),
             MACHINE_SHORT[r["machine"]], commit_cell(r), cmd_cell(r["command"])]
            for r in sorted(style_all, key=sort_key)]
    return L + table(["scene, size", "how", "minutes", "steps", "style loss / 2D AdaIN", "content / 2D AdaIN",
                      "short / long RMSE", "machine", "commit", "command"], rows) + [""]


def consistency_section(cons):
    L = ["## Consistency: rays per block and what they cost", "",
         "StyleRF renders features at 1/4 of the view and decodes them; averaging several content rays per 4x4 "
         "block (`--supersample`) steadies the frames. The recipe uses 3x3 rays, only in blocks at edges "
         "(`--refine-contrast 0.15`), and the cheaper quincunx on forward-facing scenes of 800 px and more.", "",
         "![Consistency against rays per block](results/consistency_rays.svg)", "",
         "![Consistency against the content render's time](results/consistency_time.svg)", "",
         "Shading refined blocks once per depth slab (the default) cut fern 504x378's content from %s to %s a view "
         "at short RMSE %s against %s; on fern 1008x756 the quincunx (%s, %s) is both cheaper and steadier than "
         "3x3 (%s, %s)." % (
             said(cons, "rays-fern-504-3x3-exact", "content_s", " s"), said(cons, "rays-fern-504-3x3-slab", "content_s", " s"),
             said(cons, "rays-fern-504-3x3-slab", "short_rmse_x", "x"), said(cons, "rays-fern-504-3x3-exact", "short_rmse_x", "x"),
             said(cons, "rays-fern-1008b-quincunx", "content_s", " s"), said(cons, "rays-fern-1008b-quincunx", "short_rmse_x", "x"),
             said(cons, "rays-fern-1008b-3x3", "content_s", " s"), said(cons, "rays-fern-1008b-3x3", "short_rmse_x", "x")), ""]
    rows = [[r["model"], r["rays"], pair(num(r, "short_rmse_x"), num(r, "long_rmse_x")),
             cell(num(r, "short_lpips_x"), "x"), cell(num(r, "content_s"), " s"), cell(num(r, "frame_s"), " s"),
             MACHINE_SHORT[r["machine"]], commit_cell(r), cmd_cell(r["command"])]
            for r in sorted(cons, key=lambda r: (sort_key(r), RAYS.index(r["rays"])))]
    notes = [r for r in sorted(cons, key=sort_key) if r.get("note")]
    L += table(["model", "rays a block", "short / long RMSE", "short LPIPS", "content a view", "a frame",
                "machine", "commit", "command"], rows)
    for r in notes:
        L += ["", "%s, %s: %s." % (r["model"], r["rays"], r["note"])]
    return L + [""]


def resolution_section(runs):
    L = ["## Resolution: quality and frame time", "",
         "![Quality and frame time against resolution](results/resolution.svg)", "",
         "The same `stylerf run --minutes 90` at each size. Native size (the default) decodes sharpest at its own "
         "size; `--downsample 2` is the quick preview (a lego frame in %s, peak RSS %s against %s). The frame time "
         "plotted is the run's plan (content + one style), made the same way at every size." % (
             said(runs, "lego-400-run", "frame_s", " s"), said(runs, "lego-400-run", "peak_rss_gb", " GB"),
             said(runs, "lego-800-run", "peak_rss_gb", " GB")), ""]
    recs = sorted((r for r in runs if r.get("top") and r["scene"] in ("lego", "fern")), key=sort_key)
    rows = [[scene_size(r), cell(num(r, "decoded_psnr_db"), " dB"), cell(num(r, "style_ratio_x"), "x"),
             cell(num(r, "short_rmse_x"), "x"),
             "%s + %s s" % (text(num(r, "probe_content_s")), text(num(r, "probe_style_s"))),
             cell(num(r, "frame_s"), " s"), cell(num(r, "peak_rss_gb"), " GB"), MACHINE_SHORT[r["machine"]],
             commit_cell(r)] for r in recs]
    return L + table(["scene, size", "decoded", "style loss / 2D AdaIN", "short RMSE", "plan: content + a style",
                      "measured frame", "peak RSS", "machine", "commit"], rows) + [""]


def budget_section(runs):
    recs = sorted((r for r in runs if num(r, "report_min") is not None), key=sort_key)
    if not recs:
        return []
    L = ["## Where a run's minutes go", "",
         "`stylerf run` gives its report (held-out renders, the probe, eval style, videos, mix sheet, consistency "
         "table) at most 15% of `--minutes` and training the rest, shrinking the videos and then the scores to fit. "
         "Training: the three stages' wall time; report: every other step.", ""]
    rows = [[scene_size(r), cell(num(r, "total_min"), " min"), cell(num(r, "density_min"), " min"),
             cell(num(r, "features_min"), " min"), cell(num(r, "style_min"), " min"),
             cell(num(r, "report_min"), " min"), cell(num(r, "training_share_pct"), "%"),
             "**%s** / %s / %s" % (cell(num(r, "style_ratio_x"), "x"), cell(num(r, "content_ratio_x"), "x"),
                                   cell(num(r, "structure_lpips_x"), "x")),
             MACHINE_SHORT[r["machine"]] + ", " + r["date"], commit_cell(r), cmd_cell(r["command"]),
             r.get("note", "")] for r in recs]
    return L + table(["scene, size", "time", "density", "features", "style", "report", "training",
                      "style / content / LPIPS to the truth, over 2D AdaIN's", "machine, date", "commit",
                      "command", "note"], rows) + [""]


def demo_section(demo):
    L = ["## The demo on each host", "",
         "%s (it runs %s), after the build; *empty*: the first run after installing (OpenCL programs compiled), "
         "*warm*: compiled programs cached." % (cmd_cell(demo[0]["command"]), cmd_cell(demo[0]["runs"])), ""]
    return L + table(["machine", "PoCL cache", "time", "density", "decoded", "style loss / 2D AdaIN",
                      "short RMSE", "short LPIPS", "mix corners", "date", "commit"], demo_rows(demo, False)) + [""]


def gpu_section(gpu, h100, h200, root):
    L = ["## The GPU", "", "![One training step on the CPU and on a GPU](results/gpu.svg)", "",
         "`bash scripts/device_check.sh --bundle .devcarry --device gpu --out OUT` (the bundle made by "
         "`bash scripts/device_bundle.sh build .devcarry`) runs the suite, the step benches and a 2-minute lego "
         "density run on one OpenCL device and writes one JSON (docs/device/). The benches time the bench's "
         "synthetic 64^3 geometry with weights of the real shapes; the CPU rows time a lego 200x200 checkpoint's "
         "sparser geometry, so only the decoder steps are the same work on both.", ""]
    rows = []
    for r in gpu:
        a, _ = gpu_step(root, r["gpu"][0], r["gpu"][1])
        b, _ = gpu_step(root, "docs/device/h200_device_check.json", r["gpu"][1])
        rows.append([r["what"], cell(num(r, "cpu_s"), " s"), sec3(a) + " s", sec3(b) + " s", r["note"],
                     cmd_cell(r["command"])])
    L += table(["step", "2-core CPU", "H100", "H200", "geometry", "command"], rows)
    L += [""]
    drows = []
    for d, path in ((h100, "docs/device/h100_device_check.json"), (h200, "docs/device/h200_device_check.json")):
        t, dn, p = d["parts"]["tests"], d["parts"]["density"], d["projection"]
        drows.append([d["device"], "`%s`" % d["git_commit"][:7], d["date"][:10], d["weights"],
                      "%d pass, %d fail, %d need absent weights" % (t["passed"], t["failed"],
                                                                    t.get("failed_needing_weights", 0)),
                      "%d steps, %s dB (%d views)" % (dn["iterations"], dn["test_psnr"], dn["test_views"]),
                      "%.2f h (%.2f + %.2f + %.2f)" % (p["total_hours"], p["density"]["hours"],
                                                      p["features"]["hours"], p["style"]["hours"]), path])
    L += table(["device", "commit", "date", "weights", "tests", "lego 800x800 density, 2 min",
                "the paper's schedule projected (density + features + style)", "data"], drows)
    return L + [""]


KNOB_FAMILIES = ["import", "density", "features", "stylize", "evaluate", "compute"]


def viewer_section(viewer):
    L = ["## The live viewer (`stylerf view`)", "",
         "`bench/view_bench.py` drives the real page in headless Chromium and reads the page's own clock: the first "
         "preview after the page loads, preview frames a second while the camera is dragged (pointer moves every "
         "33 ms), a new picture uploaded to its first preview, the refined full frame at a new camera against "
         "`stylerf stylize` of the same camera, and the server's peak memory over minutes of dragging against "
         "`stylize`'s. The browser shares the CPU with the server.", ""]
    rows = []
    for r in viewer:
        n = lambda key: num(r, key)
        rows.append([r["scene"] + ", " + r["resolution"], cell(n("first_preview_ms"), " ms"),
                     cell(n("preview_fps"), " /s"), cell(n("drop_to_preview_ms"), " ms"),
                     "%s s / %s s = %sx" % (text(n("refined_s")), text(n("stylize_frame_s")), text(n("refined_ratio"))),
                     "%s / %s MB (%s MB over %s min)" % (text(n("server_peak_mb")), text(n("stylize_peak_mb")),
                                                        text(n("rss_drift_mb")), text(n("drag_minutes"))),
                     r["machine"] + ", " + r["date"], commit_cell(r), cmd_cell(r["command"])])
    L += table(["scene, size", "first preview", "previews dragging", "picture to preview",
                "full frame / stylize's", "server / stylize peak RSS (drift)", "machine, date", "commit",
                "command"], rows)
    return L + [""]


def mpi_section(mpi, h100):
    L = ["<a id=\"more-than-one-device\"></a>", "## More than one device (MPI)", "",
         "Each stage's same step (2 sub-batches: 2 ray slices, 2 patches or 2 styles) taken by one rank with one "
         "core and by two ranks with one core each (`mpirun --bind-to core`, `POCL_MAX_PTHREAD_COUNT=1`), one run "
         "after the other, alone on the machine. Steps a second over the training seconds each run prints "
         "(loading and kernel builds not counted). *Exchange*: taking the gradient off the device, summing it "
         "over the ranks in double (`MPI_Allreduce` over shared memory) and putting it back, each step.", ""]
    rows = []
    for r in mpi["records"]:
        n = lambda key: num(r, key)
        rows.append([r["stage"], r["step"], cell(n("one_steps_s"), " /s"), cell(n("two_steps_s"), " /s"),
                     "**%sx**" % text(n("speedup")), cell(n("gradient_mb"), " MB"),
                     "%s ms (%s%% of a step)" % (text(n("exchange_ms")), text(n("exchange_pct"))),
                     r["machine"] + ", " + r["date"], commit_cell(r), cmd_cell(r["command"])])
    L += table(["stage", "the step", "1 rank", "2 ranks", "2 / 1", "gradient a step", "exchange (2 ranks)",
                "machine, date", "commit", "command"], rows)
    pr = mpi["projection"]
    link = pr["links"]
    L += ["", "### Eight GPUs, projected", "",
          "From a step's time on one %s (docs/device/h100_device_check.json) and the paper profile's gradient "
          "(bytes B, float32: %s; %s), for N = 8 GPUs each taking one sub-batch (eight styles a step): "
          "t_N = t_1 + t_x with, as implemented (the gradient through host memory: OpenCL has no device-to-device "
          "collective), t_x = 2 B / PCIe + 2 (N - 1) / N x 2 B / link (a ring all-reduce of doubles), and, for "
          "comparison, a device-side float ring over NVLink: t_x = 2 (N - 1) / N x B / NVLink. Throughput: "
          "N t_1 / t_N steps' worth a second against one GPU. Assumed: PCIe %s GB/s each way, NVLink %s GB/s, "
          "100 Gb/s Ethernet %s GB/s, one machine's shared memory %s GB/s; latency ignored (%s)." % (
              h100["device"], cmd_cell(pr["gradient_command"]), pr["gradient_note"], text(link["pcie_gb_s"]), text(link["nvlink_gb_s"]),
              text(link["ethernet_gb_s"]), text(link["shared_memory_gb_s"]), pr["latency_note"]), ""]
    rows = []
    N = 8
    for st in pr["stages"]:
        t1 = float(h100_step(h100, st["h100_part"], st["h100_key"]))
        B = float(st["gradient_mb"]) * 1e6
        ring = 2.0 * (N - 1) / N
        host = lambda gb_s: 2 * B / (float(link["pcie_gb_s"]) * 1e9) + ring * 2 * B / (float(gb_s) * 1e9)
        cells = []
        for tx in (host(link["shared_memory_gb_s"]), host(link["ethernet_gb_s"]),
                   ring * B / (float(link["nvlink_gb_s"]) * 1e9)):
            cells.append("%.1f ms: %.1fx" % (1e3 * tx, N * t1 / (t1 + tx)))
        rows.append([st["stage"], "%.1f ms" % (1e3 * t1), cell(st["gradient_mb"], " MB")] + cells)
    L += table(["stage (paper profile)", "t_1 on one H100", "B", "one machine, host path", "8 machines, 100 GbE",
                "NVLink, device-side"], rows)
    L += ["", "What scales: styles, patches and ray slices over ranks of equal speed. What does not: the whole "
          "gradient goes round every step however few voxels the step touched (the density and feature grids), "
          "and a step waits for its slowest rank, so a CPU rank beside a GPU slows the GPU to the CPU's pace. "
          "`stylize` over ranks: [the knobs table](#other-knobs-and-choices-that-are-always-on).", ""]
    return L


def h100_step(h100, part, key):
    return h100["parts"][part][key]


def knobs_section(knobs):
    L = ["## Other knobs, and choices that are always on", "",
         "What each buys and what it costs, one measurement each (the text as recorded with its run).", ""]
    esc = lambda t: t.replace("|", "\\|") if t else "—"
    rows = [[r["family"], esc(r["knob"]), esc(r["buys"]), esc(r["costs"]), cmd_cell(r["command"]), commit_cell(r)]
            for r in sorted(knobs, key=lambda r: KNOB_FAMILIES.index(r["family"]))]
    return L + table(["for", "knob", "buys", "costs", "command", "commit"], rows) + [""]


def machines_section(machines):
    L = ["## Machines", ""]
    L += table(["name", "machine"], [[MACHINE_SHORT[k], v] for k, v in sorted(machines.items())])
    return L + ["", "The data: docs/results/*.json, one file per table (each record: id, command, commit or "
                "recorded_in, machine, date, numbers with units in the file's `fields`), and docs/device/*.json. "
                "Earlier runs and the options that measured worse are in docs/experiments.md and in git's history "
                "of this page.", ""]


# --- main --------------------------------------------------------------------------------------------------

def write_all(root, out):
    md, svgs = page(root)
    os.makedirs(os.path.join(out, "results"), exist_ok=True)
    with open(os.path.join(out, "results.md"), "w") as f:
        f.write(md)
    for name, svg in svgs.items():
        with open(os.path.join(out, "results", name), "w") as f:
            f.write(svg)
    return ["results.md"] + ["results/" + n for n in sorted(svgs)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=ROOT, help="the repository (default: this script's)")
    ap.add_argument("--out", help="write results.md and results/*.svg here instead of ROOT/docs")
    ap.add_argument("--check", action="store_true", help="regenerate into a temporary folder and diff")
    a = ap.parse_args()
    if not a.check:
        names = write_all(a.root, a.out or os.path.join(a.root, "docs"))
        print("wrote %d files: %s" % (len(names), ", ".join(names)))
        return 0
    bad = 0
    with tempfile.TemporaryDirectory(prefix="stylerf-results-") as tmp:
        for name in write_all(a.root, tmp):
            committed = os.path.join(a.root, "docs", name)
            new = open(os.path.join(tmp, name)).read().splitlines(keepends=True)
            old = open(committed).read().splitlines(keepends=True) if os.path.exists(committed) else []
            if old != new:
                bad += 1
                sys.stdout.writelines(difflib.unified_diff(old, new, "docs/" + name, "regenerated/" + name, n=1))
                print()
    if bad:
        print("%d file(s) differ from what the data gives. Regenerate and commit them:\n  %s" % (bad, COMMAND))
        return 1
    print("docs/results.md and its %d plots match docs/results/*.json and docs/device/*.json" % len(SVGS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
