"""What ``pyramid explain`` reports about an expression: exact, printable, JSON-ready."""

from __future__ import annotations

from fractions import Fraction

from pyramid_cli.core import algebra
from pyramid_cli.core.expr import Expr, kind, to_text


def _ints(m: list[list[Fraction]], den: int) -> list[list[int]]:
    return [[int(v * den) for v in row] for row in m]


def describe(expr: Expr) -> dict:
    """The ``--json`` object of ``pyramid explain`` (see the README for the fields).

    Raises :class:`~pyramid_cli.core.errors.UsageError` at once when the exact kernel is too large to
    evaluate in seconds (:func:`pyramid_cli.workflows.limits.check_kernel_cost`).
    """
    from pyramid_cli.workflows.limits import check_kernel_cost

    check_kernel_cost(expr, to_text(expr, "ascii"))
    k = algebra.kernel(expr)
    shape = algebra.display_shape(k)
    phases = []
    for key in sorted(k.phases, reverse=True):
        m, (i0, j0) = algebra.as_matrix(k.phases[key], shape)
        den = algebra.denominator([v for row in m for v in row])
        entry = {"phase": list(key), "denominator": den, "weights": _ints(m, den), "anchor": [i0, j0]}
        split = algebra.separate(m)
        if split is not None:
            col, row = split
            cd, rd = algebra.denominator(col), algebra.denominator(row)
            entry["separable"] = {"column": {"denominator": cd, "weights": [int(v * cd) for v in col]},
                                  "row": {"denominator": rd, "weights": [int(v * rd) for v in row]}}
        phases.append(entry)
    lattice, offset = algebra.lattice(k)
    cont = algebra.continuity(k)
    return {
        "expression": to_text(expr),
        "ascii": to_text(expr, "ascii"),
        "kind": kind(expr),
        "stride": k.stride[0],
        "period": k.period[0],
        "phases": phases,
        "continuity": algebra.continuity_name(cont),
        "lattice": lattice,
        "phase": [None if o is None else str(o) for o in offset],
        "fetches": algebra.paper_fetches(expr),
    }


def _matrix_lines(prefix: str, weights: list[list[int]], den: int) -> list[str]:
    scale = "" if den == 1 else f"1/{den} "
    width = max(len(str(v)) for row in weights for v in row)
    rows = [" ".join(str(v).rjust(width) for v in row) for row in weights]
    if len(rows) == 1:
        return [f"{prefix}{scale}[{rows[0]}]"]
    out = []
    for i, row in enumerate(rows):
        left, right = ("⎡", "⎤") if i == 0 else ("⎣", "⎦") if i == len(rows) - 1 else ("⎢", "⎥")
        out.append(f"{prefix if i == 0 else ' ' * len(prefix)}{scale if i == 0 else ' ' * len(scale)}"
                   f"{left}{row}{right}")
    return out


def _vector(v: dict) -> str:
    scale = "" if v["denominator"] == 1 else f"1/{v['denominator']} "
    return f"{scale}[{' '.join(str(x) for x in v['weights'])}]"


def render(info: dict) -> str:
    """The human-readable report."""
    lines = [f"expression  {info['expression']}", f"ascii       {info['ascii']}"]
    extra = {"analysis": f" (stride {info['stride']})", "synthesis": f" (period {info['period']})",
             "mixed": f" (period {info['period']}, stride {info['stride']})"}.get(info["kind"], "")
    lines.append(f"kind        {info['kind']}{extra}")
    for ph in info["phases"]:
        label = "kernel" if len(info["phases"]) == 1 else f"h^{{{ph['phase'][0]},{ph['phase'][1]}}}"
        lines += _matrix_lines(f"{label:<12}", ph["weights"], ph["denominator"])
        if "separable" in ph and len(ph["weights"]) > 1 and len(ph["weights"][0]) > 1:
            s = ph["separable"]
            lines.append(f"{'':12}= {_vector(s['column'])}ᵀ · {_vector(s['row'])}")
        lines.append(f"{'':12}anchor (offset 0) at row {ph['anchor'][0] + 1}, column {ph['anchor'][1] + 1}")
    lines.append(f"continuity  {info['continuity'] or 'n/a (not an analysis or synthesis filter)'}")
    where = {"primal": "coarse r sits at fine 2r", "dual": "coarse r sits at fine 2r − ½", "shifted": "neither"}
    lines.append(f"lattice     {info['lattice']} ({where.get(info['lattice'], 'offset')}; "
                 f"output r at input ρ·r + ({info['phase'][0]}, {info['phase'][1]}))")
    fetch = info["fetches"]
    lines.append(f"fetches     {'unknown (not in the paper)' if fetch is None else f'{fetch:g}'} "
                 "(the paper's bilinear fetch count)")
    return "\n".join(lines)


def plot_powers(expr: Expr, path: str, powers: int = 4) -> None:
    """Draw the 1-D powers (h)ᵐ of an analysis filter, like the paper's Figure 2.

    The format follows ``path``'s extension: .png, .svg or .pdf (anything else: UsageError, exit 2).
    """
    fmt = check_plot_path(path)
    from pyramid_cli.workflows.limits import check_kernel_cost

    check_kernel_cost(_power(expr, powers), f"({to_text(expr, 'ascii')})^{powers}")
    from pyramid_cli.core.errors import UsageError

    try:
        import matplotlib
    except ImportError:
        raise UsageError("--plot needs matplotlib: pip install 'bilinear-pyramid[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pyramid_cli.core.expr import Apply

    if not (isinstance(expr, Apply) and kind(expr) == "analysis"):
        raise UsageError("--plot draws the powers of an analysis filter (an expression with ⊗↓)")
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for m in range(1, powers + 1):
        k = algebra.kernel(_power(expr, m))
        s = k.stride[1]
        row: dict[int, Fraction] = {}
        for (_, dc), v in k.phases[(0, 0)].items():
            row[dc] = row.get(dc, 0) + v
        xs = sorted(row)
        # offset d reads input pixel s·r − d: plot against −d/s so the shape converges
        pts = sorted((-d / s, float(row[d]) * s) for d in xs)
        ax.step([p[0] for p in pts], [p[1] for p in pts], where="mid", label=f"m = {m}")
    ax.set_xlabel("position in coarse pixels")
    ax.set_ylabel("weight × 2ᵐ")
    ax.set_title(f"powers of {to_text(expr)}")
    ax.legend()
    fig.tight_layout()
    from pyramid_cli.imageio.atomic import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt)
    plt.close(fig)


PLOT_FORMATS = ("png", "svg", "pdf")


def check_plot_path(path: str) -> str:
    """The format ``--plot`` writes for ``path`` (its extension: png, svg or pdf); UsageError otherwise."""
    import os

    from pyramid_cli.core.errors import UsageError

    ext = os.path.splitext(os.fspath(path))[1].lower().lstrip(".")
    if ext not in PLOT_FORMATS:
        raise UsageError(f"--plot {path}: plots are written as {', '.join('.' + f for f in PLOT_FORMATS)}; "
                         f"not {'.' + ext if ext else 'a file without an extension'}")
    return ext


def _power(expr: Expr, m: int) -> Expr:
    """m repetitions of the whole chain ``expr`` (each applied to the previous result)."""
    from dataclasses import replace

    from pyramid_cli.core.expr import Input

    def graft(e: Expr, onto: Expr) -> Expr:
        if isinstance(e, Input):
            return onto
        return replace(e, arg=graft(e.arg, onto))

    out: Expr = Input()
    for _ in range(m):
        out = graft(expr, out)
    return out
