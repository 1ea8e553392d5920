"""Line plots as SVG text: a grid of panels with a linear x axis and a logarithmic y axis, what the
report's slice plots need and no more.

Written directly (no plotting library): a page of slices costs milliseconds, the file is a few
hundred kilobytes and stays sharp at any zoom.  Curves are polylines in pixel coordinates,
thinned where straight to within a fraction of a pixel; values that are not positive or not
finite break the line; values below the panel's range are drawn on its floor.
"""
from __future__ import annotations

import html
import math
from dataclasses import dataclass, field

import numpy as np

FONT = "font-family='sans-serif'"
TOLERANCE_PX = 0.5                # thinning: the most a line moves (pixels)


@dataclass
class Panel:
    """One panel: x range, y range (positive; log scale), labels and what is drawn in it."""

    x_range: tuple
    y_range: tuple = (1e-3, 1.0)
    title: str = ""
    xlabel: str = ""
    ylabel: str = ""
    xticks: tuple = ()
    items: list = field(default_factory=list)

    def line(self, x, y, color, width=1.2, opacity=1.0, dash=None):
        self.items.append(("line", np.asarray(x, float), np.asarray(y, float), color, width, opacity, dash))

    def markers(self, x, y, color, radius=2.2):
        self.items.append(("markers", np.asarray(x, float), np.asarray(y, float), color, radius))

    def light(self, x, color):
        """A triangle on the top edge at ``x``."""
        self.items.append(("light", float(x), color))


@dataclass
class Figure:
    """Panels in ``rows`` x ``cols``; a title above and a legend below."""

    rows: int
    cols: int
    panel_size: tuple = (300, 190)
    title: list = field(default_factory=list)
    legend: list = field(default_factory=list)     # (label, kind, color): kind "line", "band", "light", "dash"

    panels: dict = field(default_factory=dict)

    def panel(self, r, c, **kw) -> Panel:
        self.panels[r, c] = Panel(**kw)
        return self.panels[r, c]

    def svg(self) -> str:
        pw, ph = self.panel_size
        left, right, top, gap_x, gap_y = 62, 12, 20 + 16 * len(self.title), 44, 58
        width = left + self.cols * pw + (self.cols - 1) * gap_x + right
        legend, legend_h = _legend(self.legend, left, width - right)
        height = top + self.rows * ph + self.rows * gap_y + legend_h
        out = [f"<svg xmlns='http://www.w3.org/2000/svg' width='{width}' height='{height}' "
               f"viewBox='0 0 {width} {height}' {FONT} font-size='11'>",
               f"<rect width='{width}' height='{height}' fill='white'/>"]
        for i, line in enumerate(self.title):
            out.append(f"<text x='{width / 2:.0f}' y='{16 + 16 * i}' text-anchor='middle' font-size='13'>"
                       f"{html.escape(line)}</text>")
        placed = [(p, left + c * (pw + gap_x), top + 14 + r * (ph + gap_y))
                  for (r, c), p in sorted(self.panels.items())]
        xs, ys, oks, lengths, counts = [], [], [], [], []
        mxs, mys, m_sizes, m_counts = [], [], [], []
        for p, x0, y0 in placed:            # every line and marker of the figure mapped together
            px, py = _axes(p, x0, y0, pw, ph)
            lines = [item for item in p.items if item[0] == "line"]
            counts.append(len(lines))
            if lines:
                y = np.concatenate([it[2] for it in lines])
                xs.append(px(np.concatenate([it[1] for it in lines])))
                ys.append(py(y))
                oks.append(np.isfinite(y) & (y > 0))
                lengths += [it[1].size for it in lines]
            marks = [item for item in p.items if item[0] == "markers"]
            m_counts.append(len(marks))
            if marks:
                y = np.concatenate([it[2] for it in marks])
                ok = np.isfinite(y) & (y > 0)
                mxs.append(px(np.concatenate([it[1] for it in marks])[ok]))
                mys.append(py(y[ok]))
                valid_before = np.concatenate([[0], np.cumsum(ok)])      # valid points of each item
                m_sizes += np.diff(valid_before[np.cumsum([0] + [it[1].size for it in marks])]).tolist()
        paths = iter(_line_paths(xs, ys, oks, lengths))
        points = iter(_split(_tenths(np.concatenate(mxs), np.concatenate(mys)), m_sizes) if mxs else [])
        markers: dict[tuple, str] = {}
        for (p, x0, y0), k, m in zip(placed, counts, m_counts):
            out += _panel(p, x0, y0, pw, ph, [next(paths) for _ in range(k)], [next(points) for _ in range(m)],
                          markers)
        out.insert(2, "<defs>" + "".join(_marker(name, color, r) for (color, r), name in markers.items()) + "</defs>")
        out.append(f"<g transform='translate(0,{height - legend_h})'>")
        out += legend
        out.append("</g></svg>")
        return "\n".join(out)


CHAR_PX = 6.4                     # the legend's estimate of a character's width at font-size 11


def _legend(entries, x_min, x_max):
    """The legend's elements, entries left to right wrapped into rows, and its height."""
    out, x, y = [], x_min, 12
    for label, kind, color in entries:
        w = 40 + CHAR_PX * len(label)
        if x > x_min and x + w > x_max:
            x, y = x_min, y + 18
        if kind == "band":
            out.append(f"<line x1='{x}' y1='{y}' x2='{x + 24}' y2='{y}' stroke='{color}' stroke-width='5' "
                       f"stroke-opacity='0.3'/><circle cx='{x + 12}' cy='{y}' r='2.6' fill='none' stroke='{color}'/>")
        elif kind == "light":
            out.append(_triangle(x + 12, y - 4, color))
        else:
            dash = " stroke-dasharray='5,3'" if kind == "dash" else ""
            out.append(f"<line x1='{x}' y1='{y}' x2='{x + 24}' y2='{y}' stroke='{color}' stroke-width='1.6'{dash}/>")
        out.append(f"<text x='{x + 30:.0f}' y='{y + 4}'>{html.escape(label)}</text>")
        x += w + 16
    return out, y + 14


def _y_ticks(la, lb):
    """Tick values of a log axis from 10^la to 10^lb: every decade (every second above 6), and
    2 and 5 times each where the range spans less than two."""
    span = lb - la
    step = 2 if span > 6 else 1
    ticks = [10.0 ** d for d in range(math.ceil(la), math.floor(lb) + 1, step)]
    if span < 2:
        ticks = [m * 10.0 ** d for d in range(math.floor(la), math.ceil(lb) + 1) for m in (1, 2, 5)]
    return [t for t in ticks if la <= math.log10(t) <= lb]


def _tick_text(t):
    d = math.floor(math.log10(t) + 1e-9)
    m = round(t / 10.0 ** d)
    return f"{m}e{d}" if m != 1 else f"1e{d}"


def _triangle(x, y, color):
    return (f"<path d='M{x - 5:.1f},{y - 4:.1f}L{x + 5:.1f},{y - 4:.1f}L{x:.1f},{y + 5:.1f}Z' fill='{color}' "
            "stroke='black' stroke-width='0.5'/>")


def _axes(p, x0, y0, w, h):
    """The panel's value-to-pixel maps (px, py) for its origin ``x0, y0`` and size ``w, h``."""
    (xa, xb), (ya, yb) = p.x_range, p.y_range
    la, lb = math.log10(ya), math.log10(yb)

    def px(x):
        return x0 + (np.asarray(x, float) - xa) / (xb - xa) * w

    def py(y):
        with np.errstate(divide="ignore", invalid="ignore"):
            ly = np.log10(np.asarray(y, float))
        return y0 + h - (np.clip(ly, la, lb) - la) / (lb - la) * h
    return px, py


def _marker(name, color, r):
    """A hollow circle of radius ``r`` pixels drawn at every vertex of a path in tenths of a pixel."""
    return (f"<marker id='{name}' markerUnits='userSpaceOnUse' overflow='visible'>"
            f"<circle r='{10 * r:g}' fill='none' stroke='{color}' stroke-width='8'/></marker>")


def _panel(p, x0, y0, w, h, line_paths, marker_points, markers):
    """The panel's elements; ``line_paths``: per line item, in order, its path data (`_line_paths`);
    ``marker_points``: per markers item, in order, its valid points (`_tenths`); ``markers``:
    {(colour, radius): marker id} of the figure, those this panel uses added."""
    px, py = _axes(p, x0, y0, w, h)
    la, lb = math.log10(p.y_range[0]), math.log10(p.y_range[1])
    out = [f"<text x='{x0 + w / 2:.0f}' y='{y0 - 6}' text-anchor='middle' font-size='12'>{html.escape(p.title)}</text>"]
    clip = f"c{x0}_{y0}"
    out.append(f"<clipPath id='{clip}'><rect x='{x0}' y='{y0}' width='{w}' height='{h}'/></clipPath>")
    ticks = _y_ticks(la, lb)
    for t, y in zip(ticks, py(np.array(ticks)).tolist()):
        out.append(f"<line x1='{x0}' y1='{y:.1f}' x2='{x0 + w}' y2='{y:.1f}' stroke='#e6e6e6'/>"
                   f"<text x='{x0 - 4}' y='{y + 4:.1f}' text-anchor='end' font-size='10'>{_tick_text(t)}</text>")
    for t, x in zip(p.xticks, px(np.array(p.xticks, float)).tolist()):
        out.append(f"<line x1='{x:.1f}' y1='{y0}' x2='{x:.1f}' y2='{y0 + h}' stroke='#e6e6e6'/>"
                   f"<text x='{x:.1f}' y='{y0 + h + 13}' text-anchor='middle' font-size='10'>{t:g}</text>")
    out.append(f"<g clip-path='url(#{clip})'>")
    paths, points = iter(line_paths), iter(marker_points)
    lights = []
    for item in p.items:
        if item[0] == "line":               # in tenths of a pixel: integers are quick to write
            _, x, y, color, width, opacity, dash = item
            extra = (f" stroke-opacity='{opacity}'" if opacity < 1 else "") + \
                (f" stroke-dasharray='{','.join(str(10 * float(v)) for v in dash.split(','))}'" if dash else "")
            for d in next(paths):
                out.append(f"<path transform='scale(0.1)' d='{d}' fill='none' stroke='{color}' "
                           f"stroke-width='{10 * width:g}' stroke-linejoin='round'{extra}/>")
        elif item[0] == "markers":          # one path through the points, a circle at each vertex
            _, x, y, color, r = item
            xy = next(points)
            if len(xy) == 2:                # a path of one point: not every renderer marks it
                xy *= 2
            if xy:
                m = markers.setdefault((color, r), f"m{len(markers)}")
                out.append(f"<path transform='scale(0.1)' d='{_moveto(xy)}' fill='none' stroke='none' "
                           f"marker-start='url(#{m})' marker-mid='url(#{m})' marker-end='url(#{m})'/>")
        else:
            lights.append(item)
    out.append("</g>")
    out.append(f"<rect x='{x0}' y='{y0}' width='{w}' height='{h}' fill='none' stroke='#444'/>")
    out += [_triangle(float(px(x)), y0, color) for _, x, color in lights]
    if p.xlabel:
        out.append(f"<text x='{x0 + w / 2:.0f}' y='{y0 + h + 28}' text-anchor='middle'>{html.escape(p.xlabel)}</text>")
    if p.ylabel:
        out.append(f"<text transform='translate({x0 - 42},{y0 + h / 2:.0f}) rotate(-90)' text-anchor='middle'>"
                   f"{html.escape(p.ylabel)}</text>")
    return out


def _line_paths(xs, ys, oks, lengths):
    """Per line (pixel coordinates and where valid: the concatenations of ``xs``, ``ys`` and
    ``oks`` hold the lines end to end, ``lengths`` long): the SVG path data of each run of two or
    more valid points, thinned (see TOLERANCE_PX); every line of a figure thinned and written
    together (numpy's cost is per call)."""
    if not lengths:
        return []
    x, y, ok = np.concatenate(xs), np.concatenate(ys), np.concatenate(oks)
    ends = np.cumsum(lengths)
    begins = ends - lengths
    after = np.zeros(ok.size + 1, bool)         # ok[i - 1] within the line, at i
    after[1:] = ok
    after[begins] = False
    before = np.zeros(ok.size, bool)            # ok[i + 1] within the line, at i
    before[:-1] = ok[1:]
    before[ends - 1] = False
    starts = np.flatnonzero(ok & ~after[:-1])
    stops = np.flatnonzero(ok & ~before) + 1
    long = stops - starts >= 2
    starts, stops = starts[long], stops[long]
    line_of = np.searchsorted(ends, starts, side="right")
    out: list[list[str]] = [[] for _ in lengths]
    if not starts.size:
        return out
    keep, run_of = _thin_runs(x, y, starts, stops)
    xy = _tenths(x[keep], y[keep])
    bounds = (np.searchsorted(run_of, np.arange(starts.size + 1)) * 2).tolist()
    for line, a, b in zip(line_of.tolist(), bounds[:-1], bounds[1:]):
        out[line].append(_moveto(xy[a:b]))
    return out


def _tenths(x, y) -> list[int]:
    """Pixel coordinates as the paths hold them: x0, y0, x1, y1, ... in tenths of a pixel (integers
    are quick to write; a path drawn with transform='scale(0.1)')."""
    return np.rint(np.stack([x, y], -1) * 10).astype(np.int64).ravel().tolist()


def _split(xy: list, sizes) -> list[list[int]]:
    """`_tenths`' list of points cut into consecutive parts of ``sizes`` points."""
    ends = np.cumsum(sizes).tolist()
    return [xy[2 * a:2 * b] for a, b in zip([0] + ends[:-1], ends)]


def _moveto(xy) -> str:
    """Path data through the points ``xy`` (`_tenths`): a moveto and implicit linetos."""
    return "M" + " ".join(map(str, xy))


def _thin(x, y, passes=4):
    """Indices of the points of one line that thinning keeps (`_thin_runs`)."""
    return _thin_runs(np.asarray(x, float), np.asarray(y, float), np.array([0]), np.array([np.size(x)]), passes)[0]


def _thin_runs(x, y, starts, stops, passes=4):
    """The points kept of the runs ``[starts[i], stops[i])`` of ``x``, ``y``, in order, and the run
    each belongs to.  Pass k drops points closer than TOLERANCE_PX / 2^(k+1) to the chord of their
    neighbours, never two neighbours at once and never a run's ends; a dropped point's distance
    from the final line is at most the sum of those, below TOLERANCE_PX."""
    lengths = stops - starts
    run_of = np.repeat(np.arange(starts.size), lengths)
    keep = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths - starts, lengths)
    fixed = np.zeros(keep.size, bool)
    fixed[np.cumsum(lengths) - lengths] = True
    fixed[np.cumsum(lengths) - 1] = True
    for k in range(passes):
        if keep.size < 3:
            break
        xs, ys = x[keep], y[keep]
        dx, dy = xs[2:] - xs[:-2], ys[2:] - ys[:-2]
        dist = np.abs(dx * (ys[1:-1] - ys[:-2]) - dy * (xs[1:-1] - xs[:-2])) / np.maximum(np.hypot(dx, dy), 1e-9)
        drop = (dist < TOLERANCE_PX / 2 ** (k + 1)) & ~fixed[1:-1]
        drop[1::2] = False        # never two neighbours in one pass; a run's interior points have its own as neighbours
        if not drop.any():
            break
        mask = np.ones(keep.size, bool)
        mask[1:-1] = ~drop
        keep, run_of, fixed = keep[mask], run_of[mask], fixed[mask]
    return keep, run_of
