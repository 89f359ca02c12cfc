"""Parameter sets: frozen dataclasses, named cited sets, validation, TOML I/O."""

from dampersim.parameters.model import (
    ArcSpring,
    DamperSystem,
    Friction,
    Hardstops,
    Inertias,
    OutputMotor,
    Rig,
    RigElement,
    Solver,
    SpringFriction,
    SpringSet,
)
from dampersim.parameters.io import (
    dotted_names,
    dumps_toml,
    load_toml,
    loads_toml,
    parse_set_options,
    save_toml,
    system_from_dict,
    to_dict,
    with_updates,
)
from dampersim.parameters.validation import validate
from dampersim.parameters.sets import DEFAULT_SET, SETS
from dampersim.errors import ParameterError

#: the thesis's own discretisation ([thesis] §6.2.2): 18 outer and 8 inner segments, the
#: default until the accuracy grid chose 48/16 (docs/model.md §12)
THESIS_SEGMENTS = {"solver.outer_segments": 18, "solver.inner_segments": 8}


def default_parameters(name: str = DEFAULT_SET) -> DamperSystem:
    """The named parameter set (default: the thesis's turbine damper on the test rig)."""

    if name not in SETS:
        raise ParameterError("parameter set", name, f"one of {sorted(SETS)}")
    return SETS[name]()


def at_thesis_segments(system: DamperSystem | None = None) -> DamperSystem:
    """``system`` (the default set if None) with the thesis's segment counts, THESIS_SEGMENTS."""

    return with_updates(system or default_parameters(), THESIS_SEGMENTS)


def load_parameters(path=None, updates=None) -> DamperSystem:
    """Load a TOML parameter file (or the default set when ``path`` is None) and apply
    dotted overrides ``updates`` ({"friction.outer.alpha": 0, ...}); validated."""
    system = default_parameters() if path is None else load_toml(path)
    if updates:
        system = with_updates(system, updates)
    return system


__all__ = [
    "ArcSpring", "DamperSystem", "Friction", "Hardstops", "Inertias", "OutputMotor", "Rig",
    "RigElement", "Solver", "SpringFriction", "SpringSet", "dotted_names", "dumps_toml",
    "load_toml", "loads_toml", "parse_set_options", "save_toml", "system_from_dict", "to_dict",
    "with_updates", "validate", "default_parameters", "load_parameters", "DEFAULT_SET", "SETS", "THESIS_SEGMENTS", "at_thesis_segments",
]
