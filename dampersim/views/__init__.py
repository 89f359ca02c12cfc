"""The data behind each dashboard page, as plain library code (no Dash): the pages call it,
and so can tests, benchmarks and notebooks.

One module per concern: :mod:`~dampersim.views.state` (page state in the URL),
:mod:`~dampersim.views.params` (parameter overrides and stored sets),
:mod:`~dampersim.views.store` (the view cache and its keys),
:mod:`~dampersim.views.notices` (notices and query values), and one module per page's
computation: :mod:`~dampersim.views.explorer`, :mod:`~dampersim.views.segments`,
:mod:`~dampersim.views.sweeps` (Colourmap and Maps), :mod:`~dampersim.views.hysteresis`,
:mod:`~dampersim.views.pulsation`, :mod:`~dampersim.views.studies`,
:mod:`~dampersim.views.discrepancy` and :mod:`~dampersim.views.rigdata` (importing a rig
recording on the Discrepancy page). Page views return figures (built by :mod:`dampersim.plotting`), tables
and summary figures; the cached ones (explorer, segments, sweeps, hysteresis, discrepancy)
hold their figures as JSON-ready dicts, the uncached Pulsation and Studies views return
Plotly figure objects.

The names below are re-exported for scripts and notebooks; pages import from the
specific modules.
"""

from dampersim.views.notices import notice
from dampersim.locations import cache_dir
from dampersim.views.store import close_stores, load_parameter_set, load_view, view_key
from dampersim.views.params import (
    KEY_PARAMETERS,
    MAX_UPLOAD_BYTES,
    apply_overrides,
    accuracy_notices,
    apply_table_edits,
    base_system,
    parameter_value,
    parameters_toml,
    parameters_view,
    params_for_system,
    parse_parameters,
    parse_uploaded_parameters,
    resolve_system,
)
from dampersim.views.state import (
    MAX_LOOP_SPEEDS,
    MAX_ORDERS,
    PAGE_PATHS,
    PAGES,
    Field,
    default_state,
    format_orders,
    orders_si,
    page_href,
    parse_orders_deg,
    parse_query,
    state_from_controls,
    to_query,
)
from dampersim.views.explorer import explorer_view
from dampersim.views.segments import segments_view
from dampersim.views.sweeps import (
    SweepRegistry,
    colourmap_status,
    colourmap_view,
    maps_status,
    maps_view,
    running_sweeps,
)
from dampersim.views.hysteresis import hysteresis_view
from dampersim.views.discrepancy import (
    CAMPAIGN_ACCEPTED,
    UPLOAD_PREFIX,
    UPLOADS_SUBDIR,
    campaign_summary,
    diagnosis_seconds,
    discrepancy_choice,
    discrepancy_figures,
    discrepancy_folder,
    discrepancy_key,
    discrepancy_query,
    discrepancy_value,
    discrepancy_view,
    example_campaigns,
    parse_discrepancy_query,
    summarise_campaign,
    unpack_campaign_zip,
    upload_folder,
    upload_label,
)
from dampersim.views.pulsation import dominant_order_view, pulsation_view
from dampersim.views.studies import study_view

__all__ = [
    "PAGES",
    "PAGE_PATHS",
    "Field",
    "KEY_PARAMETERS",
    "MAX_ORDERS",
    "MAX_LOOP_SPEEDS",
    "MAX_UPLOAD_BYTES",
    "notice",
    "parse_query",
    "to_query",
    "page_href",
    "default_state",
    "state_from_controls",
    "parse_parameters",
    "resolve_system",
    "base_system",
    "apply_overrides",
    "parameter_value",
    "parse_orders_deg",
    "format_orders",
    "orders_si",
    "cache_dir",
    "close_stores",
    "view_key",
    "load_view",
    "load_parameter_set",
    "explorer_view",
    "colourmap_view",
    "colourmap_status",
    "maps_view",
    "maps_status",
    "hysteresis_view",
    "segments_view",
    "parameters_view",
    "params_for_system",
    "parse_uploaded_parameters",
    "parameters_toml",
    "accuracy_notices",
    "apply_table_edits",
    "SweepRegistry",
    "running_sweeps",
    "pulsation_view",
    "dominant_order_view",
    "study_view",
    "CAMPAIGN_ACCEPTED",
    "UPLOAD_PREFIX",
    "UPLOADS_SUBDIR",
    "example_campaigns",
    "unpack_campaign_zip",
    "upload_folder",
    "upload_label",
    "parse_discrepancy_query",
    "discrepancy_choice",
    "discrepancy_value",
    "discrepancy_query",
    "discrepancy_folder",
    "campaign_summary",
    "summarise_campaign",
    "diagnosis_seconds",
    "discrepancy_key",
    "discrepancy_view",
    "discrepancy_figures",
]
