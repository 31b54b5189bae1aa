"""A route: how a stack of planes is made from one light field, parsed once from its name.

The command line (``profiles --route``, ``sequence --route``), the recordings' job
(:mod:`lf_flame.recordings.job`), the diagnostics (:func:`lf_flame.measure.diagnostics.measure_settings`)
and the experiments name routes by strings; :func:`parse_route` turns a name into one
:class:`Route` that says what the planes are (``kind``), what makes them (``solver``) and
with which settings (``knobs``). Light: imports no numerical library.

Names:

- refocusing (``kind="refocus"``): ``shift-sum``, ``shift-sum-nearest``, ``fourier``
  (:func:`lf_flame.refocus.shift_and_sum.refocus`), and the tomography's normalised adjoint,
  ``reconstruct-adjoint`` (the command line's name) = ``refocus-adjoint`` (the experiments'):
  plain refocusing through the operator's rays. ``refocus-shift-sum`` = ``shift-sum``.
- emission (``kind="emission"``): ``reconstruct-SOLVER`` for the iterative solvers of
  :data:`lf_flame.tomo.defaults.SOLVERS`, and ``truth`` (a scene's emission on the
  reconstruction grid, :func:`lf_flame.tomo.truth.scene_truth`).
- learned (``kind="learned"``): ``network`` and its yardsticks, :data:`LEARNED_ROUTES`.
- stored (``kind="stored"``): ``ground-truth``, a dataset's stored planes.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .tomo.defaults import SOLVERS

#: What each kind of route makes: refocused planes (other planes' defocused light lies on
#: them), planes of emission, a learned model's prediction, or a dataset's stored planes.
KINDS = ("refocus", "emission", "learned", "stored")
#: Refocusing routes -> keyword arguments of :func:`lf_flame.refocus.shift_and_sum.refocus`.
REFOCUS_ROUTES = {"shift-sum": (), "shift-sum-nearest": (("interpolation", "nearest"),),
                  "fourier": (("method", "fourier"),)}
#: ``--route`` names of the learned routes -> the names they carry in a model folder.
LEARNED_ROUTES = {"network": "network", "mean-image": "mean image", "linear-gap": "linear decoder (GAP-pooled)",
                  "linear-unpooled": "linear decoder (un-pooled)"}
#: The tomography's routes, one per solver (``reconstruct-adjoint`` is plain refocusing).
RECONSTRUCT_ROUTES = tuple(f"reconstruct-{s}" for s in SOLVERS)


@dataclass(frozen=True)
class Route:
    """One way of making a stack of planes from a light field (:func:`parse_route`).

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`: ``"refocus"`` (refocused planes, measured with the
        diagnostics' defaults), ``"emission"`` (planes of emission, measured with
        :data:`lf_flame.measure.diagnostics.EMISSION_MEASURE`), ``"learned"`` or ``"stored"``.
    solver : str
        What makes the planes: ``"shift-sum"`` or ``"fourier"`` (refocusing), a solver of
        :data:`lf_flame.tomo.defaults.SOLVERS` (``"adjoint"`` included), ``"truth"``, a
        key of :data:`LEARNED_ROUTES`, or ``"ground-truth"``.
    knobs : tuple of (str, object)
        The solver's settings as (name, value) pairs (hashable); :attr:`options` as a dict.
        Refocusing: keyword arguments of :func:`lf_flame.refocus.shift_and_sum.refocus`;
        the tomography's routes: none (each solver's defaults).
    name : str
        The name parsed (kept for labels; not part of equality).
    """

    kind: str
    solver: str
    knobs: tuple = ()
    name: str = field(default="", compare=False)

    @property
    def options(self) -> dict:
        """:attr:`knobs` as a dict of keyword arguments."""
        return dict(self.knobs)

    @property
    def emission(self) -> bool:
        """Whether the planes are emission (no other plane's defocused light on them)."""
        return self.kind == "emission"

    @property
    def tomographic(self) -> bool:
        """Whether :func:`lf_flame.tomo.solvers.reconstruct` makes the planes (``solver`` is one of its solvers)."""
        return self.solver in SOLVERS


def route_names() -> tuple:
    """Every name :func:`parse_route` accepts, aliases included."""
    return (*REFOCUS_ROUTES, "refocus-shift-sum", "refocus-adjoint", *RECONSTRUCT_ROUTES, "truth",
            *LEARNED_ROUTES, "ground-truth")


def parse_route(text) -> Route:
    """The :class:`Route` of a route's name (a :class:`Route` is returned as it is).

    Parameters
    ----------
    text : str or Route
        A name of :func:`route_names` (see the module's docstring).

    Returns
    -------
    Route

    Raises
    ------
    ValueError
        An unknown name (the message lists the known ones).
    """
    if isinstance(text, Route):
        return text
    name = str(text)
    key = name[len("refocus-"):] if name == "refocus-shift-sum" else name
    if key in REFOCUS_ROUTES:
        return Route("refocus", "fourier" if key == "fourier" else "shift-sum", REFOCUS_ROUTES[key], name)
    if name in ("refocus-adjoint", "reconstruct-adjoint"):
        return Route("refocus", "adjoint", (), name)
    if name.startswith("reconstruct-") and name[len("reconstruct-"):] in SOLVERS:
        return Route("emission", name[len("reconstruct-"):], (), name)
    if name == "truth":
        return Route("emission", "truth", (), name)
    if name in LEARNED_ROUTES:
        return Route("learned", name, (), name)
    if name == "ground-truth":
        return Route("stored", "ground-truth", (), name)
    raise ValueError(f"unknown route {name!r}; the routes are: {', '.join(route_names())}")


def measure_settings(route) -> dict:
    """Keyword arguments of :func:`lf_flame.measure.diagnostics.measure_flame` for the planes of ``route``.

    Parameters
    ----------
    route : str or lf_flame.routes.Route
        A route's name (:func:`parse_route`) or the parsed route.

    Returns
    -------
    dict
        :data:`lf_flame.measure.diagnostics.EMISSION_MEASURE` for planes of emission (``kind == "emission"``: the
        iterative solvers' ``"reconstruct-<solver>"``, and ``"truth"``, the scene's emission
        on the reconstruction grid); the defaults (an empty dict) for every other route:
        refocused planes (``"shift-sum"``, ``"fourier"``, and the tomography's adjoint,
        ``"reconstruct-adjoint"`` = ``"refocus-adjoint"``, which is plain refocusing), a
        network's prediction, a dataset's stored planes.

    Raises
    ------
    ValueError
        An unknown route name.
    """
    from .measure.diagnostics import EMISSION_MEASURE   # here: the command line imports this module light
    return dict(EMISSION_MEASURE) if parse_route(route).emission else {}
