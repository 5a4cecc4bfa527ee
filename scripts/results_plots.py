"""Small, dependency-free SVG plots for docs/results.md (scripts/make_results.py).

Three kinds, each with axes, ticks, units and a legend, written as plain SVG text so that the same data
always gives the same bytes:

  scatter(...)  points by series on linear or log axes (a categorical x axis too), optionally joined
  panels(...)   several scatter plots side by side under one title and one legend
  bars(...)     horizontal grouped bars on a log axis (one group per task, one bar per machine)

Coordinates are printed with one decimal, numbers in labels by fixed rules, so the output is stable.
"""
import math
from xml.sax.saxutils import escape

# Okabe-Ito colours (distinguishable with the common colour-vision deficiencies), yellow left out.
COLOURS = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000"]
MARKERS = ["circle", "square", "triangle", "diamond", "down"]  # "cross" is kept for a series to name
FONT = "font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\""
CHAR_W = 0.58  # a character's width in em, for laying out legends


def _f(v):
    """A coordinate: one decimal, no negative zero."""
    s = "%.1f" % v
    return "0.0" if s == "-0.0" else s


def _text(x, y, s, size=12, anchor="start", weight=None, rotate=None, fill="#222"):
    attrs = "x=\"%s\" y=\"%s\" font-size=\"%d\" text-anchor=\"%s\" fill=\"%s\"" % (_f(x), _f(y), size, anchor, fill)
    if weight:
        attrs += " font-weight=\"%s\"" % weight
    if rotate is not None:
        attrs += " transform=\"rotate(%d %s %s)\"" % (rotate, _f(x), _f(y))
    return "<text %s>%s</text>" % (attrs, escape(s))


def _marker(kind, x, y, colour, hollow=False, r=4.5):
    fill = "#fff" if hollow else colour
    style = "fill=\"%s\" stroke=\"%s\" stroke-width=\"1.6\"" % (fill, colour)
    if kind == "circle":
        return "<circle cx=\"%s\" cy=\"%s\" r=\"%s\" %s/>" % (_f(x), _f(y), _f(r), style)
    if kind == "square":
        s = r * 0.9
        return "<rect x=\"%s\" y=\"%s\" width=\"%s\" height=\"%s\" %s/>" % (
            _f(x - s), _f(y - s), _f(2 * s), _f(2 * s), style)
    if kind == "cross":
        s = r
        return ("<path d=\"M%s %sL%s %sM%s %sL%s %s\" stroke=\"%s\" stroke-width=\"2.2\" fill=\"none\"/>" %
                (_f(x - s), _f(y - s), _f(x + s), _f(y + s), _f(x - s), _f(y + s), _f(x + s), _f(y - s), colour))
    if kind == "triangle":
        pts = [(x, y - r * 1.2), (x + r * 1.1, y + r * 0.8), (x - r * 1.1, y + r * 0.8)]
    elif kind == "down":
        pts = [(x, y + r * 1.2), (x + r * 1.1, y - r * 0.8), (x - r * 1.1, y - r * 0.8)]
    else:  # diamond
        pts = [(x, y - r * 1.2), (x + r * 1.1, y), (x, y + r * 1.2), (x - r * 1.1, y)]
    return "<polygon points=\"%s\" %s/>" % (" ".join("%s,%s" % (_f(a), _f(b)) for a, b in pts), style)


def _decimals(step):
    """Decimals that print every multiple of step exactly (steps are 1, 2, 2.5 or 5 x 10^k)."""
    d = max(0, -int(math.floor(math.log10(step) + 1e-9)))
    mant = step / 10 ** math.floor(math.log10(step) + 1e-9)
    if abs(mant - 2.5) < 1e-6:
        d += 1
    return d


def _tick_label(v, decimals):
    s = "%.*f" % (decimals, v)
    return "0" if float(s) == 0 else s


class Axis:
    """A linear, log or categorical axis: the domain, the ticks and their labels."""

    def __init__(self, values, log=False, categories=None, pad=0.05, include=None, ticks=6):
        self.log = log
        self.categories = categories
        if categories:
            self.lo, self.hi = -0.5, len(categories) - 0.5
            self.ticks = [(float(i), c) for i, c in enumerate(categories)]
            return
        vals = [v for v in values if v is not None]
        if include:
            vals += list(include)
        lo, hi = min(vals), max(vals)
        if log:
            self._log_ticks(lo, hi)
        else:
            self._linear_ticks(lo, hi, pad, ticks)

    def _linear_ticks(self, lo, hi, pad, n):
        if hi == lo:
            lo, hi = lo - 1, hi + 1
        span = hi - lo
        lo, hi = (max(0.0, lo - span * pad) if lo >= 0 else lo - span * pad), hi + span * pad
        raw = (hi - lo) / max(1, n - 1)
        mag = 10 ** math.floor(math.log10(raw))
        step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw - 1e-12)
        first = math.floor(lo / step + 1e-9)
        last = math.ceil(hi / step - 1e-9)
        self.lo, self.hi = first * step, last * step
        d = _decimals(step)
        self.ticks = [(k * step, _tick_label(k * step, d)) for k in range(first, last + 1)]

    def _log_ticks(self, lo, hi):
        a = math.floor(math.log10(lo) + 1e-9)
        b = math.ceil(math.log10(hi) - 1e-9)
        if b == a:
            b += 1
        mults = (1,) if b - a >= 4 else (1, 2, 5)
        cands = [m * 10.0 ** e for e in range(a, b + 1) for m in mults if m * 10.0 ** e <= 10.0 ** b * 1.000001]
        # The domain runs from the last tick at or below the data to the first at or above it.
        self.lo = max(v for v in cands if v <= lo * 1.000001)
        self.hi = min(v for v in cands if v >= hi * 0.999999)
        ticks = [v for v in cands if self.lo <= v <= self.hi]
        self.ticks = [(v, _tick_label(v, max(0, -int(math.floor(math.log10(v) + 1e-9))))) for v in ticks]

    def frac(self, v):
        if self.log:
            return (math.log10(v) - math.log10(self.lo)) / (math.log10(self.hi) - math.log10(self.lo))
        return (v - self.lo) / (self.hi - self.lo)


def _legend(entries, x, y, width, size=12):
    """Legend entries (label, colour, marker, hollow, line) in rows under a plot; returns (svg, height)."""
    out, cx, cy, row_h = [], x, y + 14, 20
    for label, colour, marker, hollow, line in entries:
        w = 30 + len(label) * size * CHAR_W + 18
        if cx + w > x + width and cx > x:
            cx, cy = x, cy + row_h
        if line:
            out.append("<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\" stroke=\"%s\" stroke-width=\"1.6\"/>" % (
                _f(cx), _f(cy - 4), _f(cx + 22), _f(cy - 4), colour))
        if marker:
            out.append(_marker(marker, cx + 11, cy - 4, colour, hollow))
        out.append(_text(cx + 30, cy, label, size))
        cx += w
    return out, cy - y + 10


def _plot_area(p, x0, y0, w, h):
    """One scatter panel: frame, grid, ticks, axis labels, series. p is a dict (see scatter())."""
    xs = [pt["x"] for s in p["series"] for pt in s["points"]]
    ys = [pt["y"] for s in p["series"] for pt in s["points"]]
    xa = Axis(xs, log=p.get("x_log", False), categories=p.get("x_categories"), include=p.get("x_include"))
    ya = Axis(ys, log=p.get("y_log", False), include=p.get("y_include"))
    out = []
    if p.get("subtitle"):
        out.append(_text(x0 + w / 2, y0 - 8, p["subtitle"], 13, "middle", "bold"))
    out.append("<rect x=\"%s\" y=\"%s\" width=\"%s\" height=\"%s\" fill=\"#fff\" stroke=\"#444\"/>" % (
        _f(x0), _f(y0), _f(w), _f(h)))
    X = lambda v: x0 + xa.frac(v) * w
    Y = lambda v: y0 + h - ya.frac(v) * h
    for v, lab in xa.ticks:
        out.append("<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\" stroke=\"#e4e4e4\"/>" % (
            _f(X(v)), _f(y0), _f(X(v)), _f(y0 + h)))
        out.append(_text(X(v), y0 + h + 16, lab, 11, "middle"))
    for v, lab in ya.ticks:
        out.append("<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\" stroke=\"#e4e4e4\"/>" % (
            _f(x0), _f(Y(v)), _f(x0 + w), _f(Y(v))))
        out.append(_text(x0 - 6, Y(v) + 4, lab, 11, "end"))
    out.append(_text(x0 + w / 2, y0 + h + 36, p["x_label"], 12, "middle"))
    out.append(_text(x0 - 46, y0 + h / 2, p["y_label"], 12, "middle", rotate=-90))
    for ref in p.get("y_refs", []):  # a horizontal reference line, e.g. 1.0 = as good as 2D AdaIN
        yv, label = ref
        if ya.lo <= yv <= ya.hi:
            out.append("<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\" stroke=\"#888\" stroke-dasharray=\"5,4\"/>"
                       % (_f(x0), _f(Y(yv)), _f(x0 + w), _f(Y(yv))))
            out.append(_text(x0 + w - 4, Y(yv) - 4, label, 10, "end", fill="#666"))
    labels, placed = [], []
    for s in p["series"]:
        pts = s["points"]
        if s.get("line") and len(pts) > 1:
            path = sorted(pts, key=lambda q: q["x"])
            out.append("<polyline points=\"%s\" fill=\"none\" stroke=\"%s\" stroke-width=\"1.4\"/>" % (
                " ".join("%s,%s" % (_f(X(q["x"])), _f(Y(q["y"]))) for q in path), s["colour"]))
        for q in pts:
            out.append(_marker(s["marker"], X(q["x"]), Y(q["y"]), s["colour"], q.get("hollow", False)))
            placed.append((X(q["x"]) - 5, Y(q["y"]) - 5, X(q["x"]) + 5, Y(q["y"]) + 5))
            if q.get("label"):
                labels.append((X(q["x"]), Y(q["y"]), q["label"]))
    for x, y, label in labels:  # after every marker, clear of the markers and of each other
        out.append(_place_label(placed, x, y, label))
    return out


def _place_label(placed, x, y, label, size=10):
    """A point's label above-right of it, or the first other corner where it overlaps no label placed yet."""
    w, h = len(label) * size * CHAR_W, size
    for dx, dy, anchor in ((7, -6, "start"), (7, 14, "start"), (-7, -6, "end"), (-7, 14, "end")):
        x0 = x + dx if anchor == "start" else x + dx - w
        box = (x0, y + dy - h, x0 + w, y + dy)
        if not any(box[0] < b[2] and b[0] < box[2] and box[1] < b[3] and b[1] < box[3] for b in placed):
            break
    placed.append(box)
    return _text(x + dx, y + dy, label, size, anchor, fill="#333")


def _style_series(series):
    """Gives each series a colour and a marker, in order, unless it names its own."""
    for i, s in enumerate(series):
        s.setdefault("colour", COLOURS[i % len(COLOURS)])
        s.setdefault("marker", MARKERS[(i + i // len(MARKERS)) % len(MARKERS)])
    return series


def _document(width, height, title, body):
    head = ("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%d\" height=\"%d\" viewBox=\"0 0 %d %d\" %s>"
            % (width, height, width, height, FONT))
    parts = [head, "<title>%s</title>" % escape(title),
             "<rect width=\"100%\" height=\"100%\" fill=\"#fff\"/>", _text(width / 2, 24, title, 15, "middle", "bold")]
    return "\n".join(parts + body + ["</svg>"]) + "\n"


def panels(title, plots, legend_extra=(), panel_w=400, panel_h=300):
    """Plots side by side under one title; their series share one legend (by name)."""
    left, gap, top = 70, 80, 56 if any(p.get("subtitle") for p in plots) else 44
    width = left + len(plots) * panel_w + (len(plots) - 1) * gap + 30
    body, seen = [], {}
    for i, p in enumerate(plots):
        _style_series(p["series"])
        body += _plot_area(p, left + i * (panel_w + gap), top, panel_w, panel_h)
        for s in p["series"]:
            seen.setdefault(s["name"], (s["name"], s["colour"], s["marker"], False, s.get("line", False)))
    entries = list(seen.values()) + list(legend_extra)
    leg, leg_h = _legend(entries, left, top + panel_h + 48, width - left - 20)
    return _document(width, int(top + panel_h + 48 + leg_h + 8), title, body + leg)


def scatter(title, x_label, y_label, series, legend_extra=(), width=760, height=360, **axes):
    """One plot: series = [{name, points: [{x, y, label?, hollow?}], line?, colour?, marker?}]."""
    p = dict(axes, x_label=x_label, y_label=y_label, series=series)
    return panels(title, [p], legend_extra, panel_w=width - 100, panel_h=height)


def bars(title, value_label, groups, series_names, width=760):
    """Horizontal grouped bars on a log axis: groups = [(label, [value or None per series])]."""
    _cols = COLOURS
    label_w, top, bar_h, gap = 300, 44, 13, 12
    n = len(series_names)
    plot_w = width - label_w - 90
    group_h = n * bar_h + gap
    plot_h = len(groups) * group_h + gap
    vals = [v for _, vs in groups for v in vs if v is not None]
    xa = Axis(vals, log=True)
    X = lambda v: label_w + xa.frac(v) * plot_w
    body = ["<rect x=\"%s\" y=\"%s\" width=\"%s\" height=\"%s\" fill=\"#fff\" stroke=\"#444\"/>" % (
        _f(label_w), _f(top), _f(plot_w), _f(plot_h))]
    for v, lab in xa.ticks:
        body.append("<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\" stroke=\"#e4e4e4\"/>" % (
            _f(X(v)), _f(top), _f(X(v)), _f(top + plot_h)))
        body.append(_text(X(v), top + plot_h + 16, lab, 11, "middle"))
    body.append(_text(label_w + plot_w / 2, top + plot_h + 36, value_label, 12, "middle"))
    for gi, (label, vs) in enumerate(groups):
        gy = top + gap + gi * group_h
        body.append(_text(label_w - 8, gy + n * bar_h / 2 + 4, label, 11, "end"))
        for si, v in enumerate(vs):
            if v is None:
                continue
            y = gy + si * bar_h
            body.append("<rect x=\"%s\" y=\"%s\" width=\"%s\" height=\"%s\" fill=\"%s\"/>" % (
                _f(label_w), _f(y + 1), _f(max(1.0, X(v) - label_w)), _f(bar_h - 2), _cols[si % len(_cols)]))
            body.append(_text(X(v) + 4, y + bar_h - 3, ("%.3g s" % v), 10, fill="#333"))
    entries = [(name, _cols[i % len(_cols)], "square", False, False) for i, name in enumerate(series_names)]
    leg, leg_h = _legend(entries, label_w, top + plot_h + 48, plot_w)
    return _document(width, int(top + plot_h + 48 + leg_h + 8), title, body + leg)
