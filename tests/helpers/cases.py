"""Expressions and sizes every executor is held to (issue: named filters and written chains)."""

NAMED = ["box *v g", "box^nw *v g", "box4 *v g", "quadratic *v g", "cubic *v g", "bartlett *v g", "gauss5 *v g",
         "box * g", "box^nw * g", "bartlett", "gauss5", "gauss7", "quasi",
         "nearest", "midpoint", "doosabin", "cubic *^ g", "fourpoint"]
CHAINS = ["box\\ *v bartlett", "bartlett * (bartlett * g)", "(box4)^3 *v g", "doosabin *^ (box4 *v g)",
          "box\\ * (doosabin *^ g)", "quasi * g", "box *v^2 g", "1/8 [1 2 1; 0 2 0; 1 0 1] *v g", "[1 -1] * g",
          "(doosabin)^2 *^ ((box4)^2 *v g)", "fourpoint *^ (cubic *v g)", "box *v (midpoint *^ g)",
          "h_box^↖ ⊗ (h_midpoint ⊗↑ g)", "1/16 [1 3 3 1] *v g"]
SHAPES = [(1, 1), (1, 7), (7, 1), (2, 2), (5, 3), (17, 13), (64, 64), (129, 67)]

# The grid every plan executor is held to at every pixel (GL, CPU).
GRID_SIZES = [(1, 1), (1, 7), (2, 2), (5, 3), (17, 13), (64, 64), (129, 67), (7, 1), (3, 5), (67, 129)]
GRID_CHANNELS = [None, 3, 4, 6, 1]  # None: a 2-D (H, W) image


def step(builder, source, text, crop=None):
    """One written step of ``text`` on image ``source`` of a plan Builder."""
    from pyramid_cli.core.expr import steps
    from pyramid_cli.core.parse import parse

    ((op, f, stride),) = steps(parse(text))
    return builder.step(source, op, f, stride, crop)


def several_inputs_and_outputs(size=(17, 13)):
    """A Laplacian-style job: two inputs, intermediate levels read back (and read again later), the input itself
    read back."""
    from pyramid_cli.plan import Builder

    b = Builder(size)
    other = b.add_input(size)
    coarse = step(b, 0, "box4 *v g")
    coarser = step(b, coarse, "box *v g")
    up = step(b, coarse, "doosabin *^ g", crop=size)
    band = b.combine([(0, 1), (up, -1)], "band")
    final = b.combine([(band, 1), (other, 2)], "sum")
    return b.build("job", outputs=[0, coarse, band, coarser, final])
