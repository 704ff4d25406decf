"""What to compute, apart from where: one value per job the tool runs.

A :class:`Work` knows how to plan itself for the plan executors (GL, the CPU
executor, the emulator: one :class:`~pyramid_cli.plan.Plan` per input size) and
how the float64 oracle computes it (``--backend reference``: the paper's index
formulas, :mod:`pyramid_cli.reference.filters`, composed level by level). The CLI and the
Python API describe their jobs with these values and hand them to a
:class:`~pyramid_cli.exec.session.Session`; nothing else decides how a job runs.

Every job's first output comes first; pyramids that return level 0 return the
input itself there (``keeps_input``), as scikit-image's ``pyramid_gaussian`` does.
"""

from __future__ import annotations

from dataclasses import dataclass

from pyramid_cli.core import catalogue, geometry
from pyramid_cli.core.border import Border, canonical
from pyramid_cli.core.errors import InputError, UsageError
from pyramid_cli.core.expr import Expr
from pyramid_cli.core.sigma import check_sigma, sigma_blend
from pyramid_cli.plan.cache import cached
from pyramid_cli.plan.lower import plan
from pyramid_cli.plan.model import Plan
from pyramid_cli.workflows import pyramids

Size = tuple[int, int]


def _border(name: str) -> str:
    """Our name of a border mode, from ours or another library's (:data:`pyramid_cli.core.border.BORDER_ALIASES`)."""
    return canonical(name)


def _lattice_warnings(work, levels: int | None, method: str) -> list[str]:
    """A filter pair on two lattices, unless the work allows it (``--allow-mixed-lattice``)."""
    if work.allow_mixed_lattice:
        return []
    text = pyramids.lattice_mismatch(work.analysis, work.synthesis, levels, method)
    return [text] if text else []


@dataclass(frozen=True, kw_only=True)
class Work:
    """A job: its plan for given input sizes, and its reference evaluation."""

    border: str = "clamp"

    n_inputs = 1            # images the job takes (collapse: one per band)
    keeps_input = False     # output 0 is input 0 unchanged (pyramid level 0)
    label = "work"

    def plan(self, sizes: tuple[Size, ...], strategy: str = "cost") -> Plan | None:
        """The plan for inputs of ``sizes`` (rows, columns); None when there is nothing to compute.

        Made once (:meth:`make_plan`) and kept in this process and in the cache folder
        (:func:`pyramid_cli.plan.cache.cached`): a batch of same-sized files, and the next process,
        read it back instead of redoing its exact algebra."""
        pairs = tuple((int(s[0]), int(s[1])) for s in sizes)
        return cached(self, pairs, strategy, lambda: self.make_plan(pairs, strategy))

    def make_plan(self, sizes: tuple[Size, ...], strategy: str = "cost") -> Plan | None:
        """The plan for inputs of ``sizes``, computed (what every job defines; :meth:`plan` caches it)."""
        raise NotImplementedError

    def check(self, sizes: tuple[Size, ...], where: str = "") -> None:
        """Refuse work too large for inputs of ``sizes`` before it starts (:mod:`pyramid_cli.workflows.limits`);
        ``where`` (an input's path) starts the message."""

    def reference(self, images: list) -> list:
        """Every output by the float64 oracle (excluding the kept input)."""
        raise NotImplementedError

    def warnings(self, size: Size | None = None) -> list[str]:
        """What the caller should hear before this job runs on an input of ``size`` (rows, columns) or
        any size: the command line prints each as ``pyramid: warning: …``, the API as a UserWarning."""
        return []

    def notes(self, size: Size | None = None) -> list[str]:
        """What the caller is told (not warned) before this job runs: the command line prints each as
        ``pyramid: …`` on standard error, not under -q (:meth:`SigmaBlur.notes` says how it blends)."""
        return []

    def __post_init__(self) -> None:
        object.__setattr__(self, "border", _border(self.border))


@dataclass(frozen=True, kw_only=True)
class Filter(Work):
    """Any expression applied to one image (``pyramid apply``; paper §3–§5)."""

    expr: Expr | None = None
    label = "apply"

    def make_plan(self, sizes, strategy="cost"):
        return plan(self.expr, tuple(sizes[0]), strategy, self.border)

    def check(self, sizes, where=""):
        from pyramid_cli.workflows.limits import check_image_cost

        check_image_cost(self.expr, tuple(sizes[0][:2]), where=where)

    def reference(self, images):
        from pyramid_cli.reference import filters

        return [filters.run(self.expr, images[0], Border.parse(self.border))]


@dataclass(frozen=True, kw_only=True)
class Blur(Work):
    """The pyramidal blur (paper §2, Figure 3): ``levels`` analysis steps, synthesis back up.

    :meth:`warnings` names an analysis and synthesis on two lattices (as do :class:`SigmaBlur`'s,
    :class:`Fill`'s and :class:`Blend`'s) unless ``allow_mixed_lattice`` (``--allow-mixed-lattice``)."""

    levels: int = 4
    analysis: str = catalogue.DEFAULT_ANALYSIS
    synthesis: str = catalogue.DEFAULT_SYNTHESIS
    quasi: bool = False
    allow_mixed_lattice: bool = False
    label = "blur"

    def warnings(self, size=None):
        return _lattice_warnings(self, self.levels, "blur")

    def make_plan(self, sizes, strategy="cost"):
        return pyramids.blur_plan(tuple(sizes[0]), self.levels, self.analysis, self.synthesis, self.quasi, strategy,
                                  self.border)

    def reference(self, images):
        from pyramid_cli.reference import pyramids as oracle

        return [oracle.blur_reference(images[0], self.levels, self.analysis, self.synthesis, self.quasi,
                                      self.border)]


@dataclass(frozen=True, kw_only=True)
class SigmaBlur(Work):
    """A blur of Gaussian-equivalent ``sigma``: two neighbouring level counts blended."""

    sigma: float = 1.0
    analysis: str = catalogue.DEFAULT_ANALYSIS
    synthesis: str = catalogue.DEFAULT_SYNTHESIS
    allow_mixed_lattice: bool = False
    label = "blur"

    def __post_init__(self) -> None:
        super().__post_init__()
        sigma_blend(self.sigma, self.analysis, self.synthesis)  # refused (exit 2) when made, as --sigma is

    def warnings(self, size=None):
        return _lattice_warnings(self, None, "blur")

    def notes(self, size=None):
        m, t = sigma_blend(self.sigma, self.analysis, self.synthesis)
        return [f"sigma {self.sigma:g}: {1 - t:.3f} × {m} level(s) + {t:.3f} × {m + 1} "
                f"(the blend's equivalent kernel has standard deviation {self.sigma:g} px)"]

    def check(self, sizes, where=""):
        check_sigma(self.sigma, tuple(sizes[0][:2]), self.analysis, self.synthesis, where=where)

    def make_plan(self, sizes, strategy="cost"):
        return pyramids.blur_plan_sigma(tuple(sizes[0]), self.sigma, self.analysis, self.synthesis, self.border,
                                        strategy)[0]

    def reference(self, images):
        from pyramid_cli.reference import pyramids as oracle

        m, t = sigma_blend(self.sigma, self.analysis, self.synthesis)
        return [oracle.blur_blend_reference(images[0], m, t, self.analysis, self.synthesis, self.border)]


def blur_work(levels: int = 4, *, sigma: float | None = None, analysis: str = catalogue.DEFAULT_ANALYSIS,
              synthesis: str = catalogue.DEFAULT_SYNTHESIS, quasi: bool = False, border: str = "clamp",
              allow_mixed_lattice: bool = False) -> Blur | SigmaBlur:
    """The blur ``pyramid blur`` and :func:`pyramid_cli.api.blur` ask for: ``levels`` steps (:class:`Blur`), or
    Gaussian-equivalent ``sigma`` (:class:`SigmaBlur`), which the quasi-interpolation prefilter cannot join.

    Raises
    ------
    UsageError
        ``quasi`` with ``sigma``; a ``sigma`` that is not positive and finite or needs more than 16 levels.
    """
    if sigma is None:
        return Blur(levels=levels, analysis=analysis, synthesis=synthesis, quasi=quasi, border=border,
                    allow_mixed_lattice=allow_mixed_lattice)
    if quasi:
        raise UsageError("--quasi and --sigma cannot be combined")
    return SigmaBlur(sigma=sigma, analysis=analysis, synthesis=synthesis, border=border,
                     allow_mixed_lattice=allow_mixed_lattice)


@dataclass(frozen=True, kw_only=True)
class Levels(Work):
    """Levels 0..m of the analysis pyramid (paper §4), level 0 being the input.

    ``levels`` None means down to 1×1 (scikit-image's convention and a MIP chain's).
    """

    levels: int | None = None
    analysis: str = catalogue.DEFAULT_ANALYSIS
    keeps_input = True
    label = "levels"

    def count(self, size: Size) -> int:
        return geometry.mip_levels(size) if self.levels is None else self.levels

    def make_plan(self, sizes, strategy="cost"):
        m = self.count(tuple(sizes[0]))
        return pyramids.levels_plan(tuple(sizes[0]), m, self.analysis, border=self.border,
                                    strategy=strategy) if m else None

    def reference(self, images):
        from pyramid_cli.reference import pyramids as oracle

        return oracle.levels_reference(images[0], self.count(images[0].shape[:2]), self.analysis,
                                       self.border)[1:]


@dataclass(frozen=True, kw_only=True)
class Laplacian(Work):
    """Band-pass levels L_0..L_{m−1} and the coarsest G_m; :class:`Collapse` sums them back."""

    levels: int = 4
    analysis: str = catalogue.DEFAULT_ANALYSIS
    synthesis: str = catalogue.DEFAULT_SYNTHESIS
    label = "laplacian"

    def make_plan(self, sizes, strategy="cost"):
        return pyramids.levels_plan(tuple(sizes[0]), self.levels, self.analysis, True, self.synthesis, self.border,
                                    strategy)

    def reference(self, images):
        from pyramid_cli.reference import pyramids as oracle

        return oracle.laplacian_reference(images[0], self.levels, self.analysis, self.synthesis, self.border)


def same_setting(what: str, a: str, b: str) -> bool:
    """Do two spellings of a Laplacian pyramid's ``synthesis`` filter (as one ⊗↑ step) or ``border`` mean the
    same? What ``collapse`` checks against the setting its bands record (a file's, or :class:`api.Bands`')."""
    if what == "synthesis":
        from pyramid_cli.core.expr import Op, steps
        from pyramid_cli.core.parse import one_step

        return steps(one_step(a, Op.UP)) == steps(one_step(b, Op.UP))
    return a == b


@dataclass(frozen=True, kw_only=True)
class Collapse(Work):
    """G_0 = L_0 + expand(L_1 + expand(… G_m)): one input per band."""

    bands: int = 2
    synthesis: str = catalogue.DEFAULT_SYNTHESIS
    label = "collapse"

    @property
    def n_inputs(self) -> int:  # type: ignore[override]
        return self.bands

    def check(self, sizes, where=""):
        for k in range(1, len(sizes)):
            want = geometry.halved(tuple(sizes[k - 1][:2]))
            if tuple(sizes[k][:2]) != want:
                raise InputError(f"{where + ': ' if where else ''}band {k} is {sizes[k][1]}×{sizes[k][0]}; after "
                                 f"{sizes[k - 1][1]}×{sizes[k - 1][0]} it must be {want[1]}×{want[0]}")

    def make_plan(self, sizes, strategy="cost"):
        return pyramids.collapse_plan(tuple(tuple(s) for s in sizes), self.synthesis, self.border, strategy)

    def reference(self, images):
        from pyramid_cli.reference import pyramids as oracle

        return [oracle.collapse_reference(list(images), self.synthesis, self.border)]


@dataclass(frozen=True, kw_only=True)
class Fill(Work):
    """Pull-push hole filling (Kraus 2009, :mod:`pyramid_cli.workflows.methods`): inputs colours and weights
    (:func:`pyramid_cli.workflows.methods.fill_inputs` makes them from an image), output the filled colours.
    ``weight_scale`` is the pull's weight scale K and ``sweeps`` the push's smoothing sweeps, each one number
    or a pair (level 1, every coarser level)."""

    levels: int | None = None
    analysis: str = catalogue.FILL_ANALYSIS
    synthesis: str = catalogue.FILL_SYNTHESIS
    premultiplied: bool = True
    weight_scale: int | tuple[int, int] = catalogue.FILL_SCALE
    sweeps: int | tuple[int, int] = catalogue.FILL_SWEEPS
    allow_mixed_lattice: bool = False
    n_inputs = 2
    label = "fill"

    def __post_init__(self) -> None:
        from pyramid_cli.workflows.methods import fill_options

        super().__post_init__()
        scale, sweeps = fill_options(self.weight_scale, self.sweeps)  # refused (exit 2) when made
        object.__setattr__(self, "weight_scale", scale)
        object.__setattr__(self, "sweeps", sweeps)

    def warnings(self, size=None):
        return _lattice_warnings(self, None, "fill")

    def make_plan(self, sizes, strategy="cost"):
        from pyramid_cli.workflows.methods import fill_plan

        return fill_plan(tuple(sizes[0][:2]), self.levels, self.analysis, self.synthesis, self.premultiplied,
                         self.border, strategy, self.weight_scale, self.sweeps)

    def reference(self, images):
        import numpy as np

        from pyramid_cli.reference import methods as methods_reference

        colour, weight = (np.asarray(a, dtype=np.float64) for a in images)
        if self.premultiplied:
            with np.errstate(divide="ignore", invalid="ignore"):
                colour = np.where(weight > 0, colour / np.where(weight > 0, weight, 1), 0.0)
        return [methods_reference.fill(colour, weight, self.levels, self.analysis, self.synthesis, self.border,
                                       self.weight_scale, self.sweeps)]


@dataclass(frozen=True, kw_only=True)
class Blend(Work):
    """Multiresolution blending (Burt & Adelson 1983, :mod:`pyramid_cli.workflows.methods`): inputs A, B and the
    mask (the same channel count), output the blend. ``levels`` None: as many as the size allows."""

    levels: int | None = None
    analysis: str = catalogue.DEFAULT_ANALYSIS
    synthesis: str = catalogue.DEFAULT_SYNTHESIS
    allow_mixed_lattice: bool = False
    n_inputs = 3
    label = "blend"

    def count(self, size: Size) -> int:
        from pyramid_cli.workflows.methods import blend_levels

        return blend_levels((size[0], size[1])) if self.levels is None else self.levels

    def warnings(self, size=None):
        return _lattice_warnings(self, self.count(size) if size is not None else self.levels, "blend")

    def check(self, sizes, where=""):
        if len({tuple(s[:2]) for s in sizes}) > 1:
            (h0, w0), (h1, w1), (h2, w2) = (tuple(s[:2]) for s in sizes)
            raise InputError(f"{where + ': ' if where else ''}A is {w0}×{h0}, B {w1}×{h1} and the mask {w2}×{h2}: "
                             "they must have one size")

    def make_plan(self, sizes, strategy="cost"):
        from pyramid_cli.workflows.methods import blend_plan

        size = tuple(sizes[0][:2])
        return blend_plan(size, self.count(size), self.analysis, self.synthesis, self.border, strategy)

    def reference(self, images):
        import numpy as np

        from pyramid_cli.reference import methods as methods_reference

        a, b, m = (np.asarray(x, dtype=np.float64) for x in images)
        return [methods_reference.blend(a, b, m, self.count(a.shape[:2]), self.analysis, self.synthesis,
                                        self.border)]


__all__ = ["Work", "Filter", "Blur", "SigmaBlur", "Levels", "Laplacian", "Collapse", "Fill", "Blend", "same_setting",
           "blur_work"]
