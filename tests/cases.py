"""Expressions and sizes every executor is held to (issue: named filters and written chains)."""

NAMED = ["box *v g", "box^nw *v g", "box4 *v g", "quadratic *v g", "cubic *v g", "bartlett *v g", "gauss5 *v g",
         "box * g", "box^nw * g", "bartlett", "gauss5", "gauss7", "quasi",
         "nearest", "midpoint", "doosabin", "cubic *^ g", "fourpoint"]
CHAINS = ["box\\ *v bartlett", "bartlett * (bartlett * g)", "(box4)^3 *v g", "doosabin *^ (box4 *v g)",
          "box\\ * (doosabin *^ g)", "quasi * g", "box *v^2 g", "1/8 [1 2 1; 0 2 0; 1 0 1] *v g", "[1 -1] * g",
          "(doosabin)^2 *^ ((box4)^2 *v g)", "fourpoint *^ (cubic *v g)", "box *v (midpoint *^ g)",
          "h_box^↖ ⊗ (h_midpoint ⊗↑ g)", "1/16 [1 3 3 1] *v g"]
SHAPES = [(1, 1), (1, 7), (7, 1), (2, 2), (5, 3), (17, 13), (64, 64), (129, 67)]
