"""SimulationResult: SI time series of one run, with helpers for analysis and export."""

from __future__ import annotations

import base64
import dataclasses
import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from dampersim.errors import DampersimError, InputError
from dampersim.excitation import MeasuredTorque, OrderSum, TorqueRamp
from dampersim.fileio import atomic_write
from dampersim.parameters import DamperSystem, system_from_dict, to_dict
from dampersim.signal import lowpass_first_order, order_amplitudes
from dampersim.solver import layout as slots
from dampersim.solver.layout import F_PHISEG, Layout, SpringInfo
from dampersim.version import __version__

ANALYSIS_WINDOW = 1.25  # s, [thesis] §3.4 and §6.2.1


def _transducer(tout, system, rec_dt):
    """Output torque as the transducer reports it: unchanged, or with effect
    transducer_bandwidth a causal first-order low pass at its cutoff [Hz]."""
    tb = getattr(getattr(system, "effects", None), "transducer_bandwidth", None)
    if tb is None or not tb.enabled or len(tout) < 2:
        return tout

    return lowpass_first_order(tout, 1.0 / rec_dt, tb.cutoff)


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Time series of a simulation (SI units).

    t [s]; input_torque, output_torque [N m] (torque entering J_pri; shaft torque at the
    output transducer, [thesis] §6.2.1); speed_* [rad/s] absolute; windup_outer,
    windup_inner [rad] (windup of each set), windup_total [rad] (J_pri minus output
    transducer angle, the rig's measured windup); hardstop_outer/inner [N m] (contact
    torque, 0 when free); energy: dict of cumulative energies [J] (input_work, motor_work,
    kinetic, elastic, friction, damping, stacking; hardstop is the hardstop contacts'
    share of damping).
    Segment states: segment_t [s], nodes [frames, nodes] slot coordinates [rad].
    """

    t: np.ndarray
    input_torque: np.ndarray
    output_torque: np.ndarray
    speed_primary: np.ndarray
    speed_secondary: np.ndarray
    speed_tertiary: np.ndarray
    speed_motor: np.ndarray
    windup_outer: np.ndarray
    windup_inner: np.ndarray
    windup_total: np.ndarray
    hardstop_outer: np.ndarray
    hardstop_inner: np.ndarray
    motor_torque: np.ndarray
    spring_torque_outer: np.ndarray
    spring_torque_inner: np.ndarray
    energy: dict
    segment_t: np.ndarray
    nodes: np.ndarray
    springs: tuple
    spring_rows: np.ndarray = field(repr=False)
    speed: float = 0.0
    time_step: float = 0.0
    sample_rate: float = 0.0
    steady_start: float = 0.0
    wall_time: float = 0.0
    parameters: object = field(default=None, repr=False)
    excitation: object = field(default=None, repr=False)

    @classmethod
    def from_records(cls, rec, seg, layout: Layout, system, excitation, dt, rec_dt, seg_dt, wall_time):
        c = rec.T
        energy = {
            "input_work": c[slots.R_E_IN].copy(),
            "motor_work": c[slots.R_E_MOTOR].copy(),
            "kinetic": c[slots.R_E_KIN].copy(),
            "elastic": c[slots.R_E_SPRING].copy(),
            "friction": c[slots.R_E_FRIC].copy(),
            "damping": c[slots.R_E_DAMP].copy(),
            "stacking": c[slots.R_E_STACK].copy(),
            "hardstop": c[slots.R_E_HS].copy(),
        }
        return cls(
            t=c[slots.R_T].copy(),
            input_torque=c[slots.R_TIN].copy(),
            output_torque=_transducer(c[slots.R_TOUT].copy(), system, rec_dt),
            speed_primary=c[slots.R_W_PRI].copy(),
            speed_secondary=c[slots.R_W_SEC].copy(),
            speed_tertiary=c[slots.R_W_TER].copy(),
            speed_motor=c[slots.R_W_MOTOR].copy(),
            windup_outer=c[slots.R_WIND_O].copy(),
            windup_inner=c[slots.R_WIND_I].copy(),
            windup_total=c[slots.R_WIND_RIG].copy(),
            hardstop_outer=c[slots.R_HS_O].copy(),
            hardstop_inner=c[slots.R_HS_I].copy(),
            motor_torque=c[slots.R_MOTOR_T].copy(),
            spring_torque_outer=c[slots.R_SET_O].copy(),
            spring_torque_inner=c[slots.R_SET_I].copy(),
            energy=energy,
            segment_t=np.arange(seg.shape[0]) * seg_dt,
            nodes=seg,
            springs=layout.springs,
            spring_rows=layout.SF.copy(),
            speed=float(excitation.speed),
            time_step=dt,
            sample_rate=1.0 / rec_dt,
            steady_start=float(getattr(excitation, "steady_start", 0.0)),
            wall_time=wall_time,
            parameters=system,
            excitation=excitation,
        )

    # --- analysis helpers ------------------------------------------------------------
    def window(self, seconds: float = ANALYSIS_WINDOW) -> slice:
        """Slice of the last ``seconds`` [s] of the stored series (the analysis window)."""
        n = int(round(seconds * self.sample_rate))
        n = min(n, len(self.t))
        return slice(len(self.t) - n, len(self.t))

    def order_amplitudes(self, orders=tuple(range(1, 9)), seconds: float = ANALYSIS_WINDOW):
        """(input, output) order amplitudes [N m] over the analysis window ([thesis] §3.4)."""

        w = self.window(seconds)
        a_in = order_amplitudes(self.input_torque[w], self.sample_rate, self.speed, orders)
        a_out = order_amplitudes(self.output_torque[w], self.sample_rate, self.speed, orders)
        return a_in, a_out

    def energy_residual(self) -> np.ndarray:
        """Work of external torques minus (change of stored energy + dissipation) [J]."""
        e = self.energy
        stored = (e["kinetic"] - e["kinetic"][0]) + (e["elastic"] - e["elastic"][0])
        return e["input_work"] + e["motor_work"] - stored - e["friction"] - e["damping"] - e["stacking"]

    def spring_nodes(self, name: str) -> np.ndarray:
        """Slot coordinates [rad] of one spring's N+1 nodes over the segment frames."""
        for sp in self.springs:
            if sp.name == name:
                return self.nodes[:, sp.first_node:sp.first_node + sp.segments + 1]
        raise KeyError(f"spring {name!r}: accepted is one of {[s.name for s in self.springs]}")

    def segment_compression(self, name: str) -> np.ndarray:
        """Compression [rad] of each segment of spring ``name`` (relaxed arc minus arc)."""
        x = self.spring_nodes(name)
        k = [s.name for s in self.springs].index(name)
        return self.spring_rows[k, F_PHISEG] - np.diff(x, axis=1)

    def to_frame(self):
        """pandas DataFrame of the stored time series (SI column names with units)."""
        import pandas as pd

        return pd.DataFrame(
            {
                "time_s": self.t,
                "input_torque_nm": self.input_torque,
                "output_torque_nm": self.output_torque,
                "speed_primary_rad_s": self.speed_primary,
                "speed_secondary_rad_s": self.speed_secondary,
                "speed_tertiary_rad_s": self.speed_tertiary,
                "speed_motor_rad_s": self.speed_motor,
                "windup_outer_rad": self.windup_outer,
                "windup_inner_rad": self.windup_inner,
                "windup_total_rad": self.windup_total,
                "hardstop_outer_nm": self.hardstop_outer,
                "hardstop_inner_nm": self.hardstop_inner,
                "motor_torque_nm": self.motor_torque,
            }
        )

    # --- persistence -----------------------------------------------------------------
    def save(self, path) -> str:
        """Write the result to ``path`` as Parquet, atomically; returns the absolute path.

        The file is what ``python -m dampersim simulate --out FILE.parquet`` writes: one
        row per stored sample, the :meth:`to_frame` columns first, in that order (SI
        units in the names), then the set torques ``spring_torque_outer_nm`` and
        ``spring_torque_inner_nm`` and one ``energy_<name>_j`` column per cumulative
        energy. Everything that is not a series on that time base is one JSON document in
        the file's key-value metadata under the key ``dampersim.result``
        (:data:`RESULT_FORMAT`, version :data:`RESULT_FORMAT_VERSION`): the scalars
        (speed, time_step, sample_rate, steady_start, wall_time), the segment frames
        (``segment_t``, ``nodes``) and ``spring_rows`` as base64 little-endian arrays, the
        spring layout, the parameter set as the nested dict of
        :func:`dampersim.parameters.to_dict` and the excitation. Any Parquet reader
        (``pandas.read_parquet``) sees the plain time series.

        :meth:`load` gives back every array bit for bit, every scalar, the springs and an
        equal parameter set. The excitation is rebuilt exactly when it is an
        :class:`~dampersim.excitation.OrderSum`, :class:`~dampersim.excitation.TorqueRamp`
        or :class:`~dampersim.excitation.MeasuredTorque`. Any other drive (e.g. the
        recorded ramp of the discrepancy workflow, or an object of your own) cannot be
        rebuilt from a file: it is stored as, and loads back as, an
        :class:`ExcitationDescription` (class, speed, steady start, duration, repr) that
        has no ``torque(t)``; the ``input_torque`` series holds the torque it produced.

        Segment frames of very long runs (above about 100 MB) exceed the default metadata
        size limit of Parquet readers; :meth:`load` lifts that limit, pandas needs
        ``thrift_string_size_limit`` for such a file.
        """

        import pyarrow as pa
        import pyarrow.parquet as pq

        frame = self.to_frame()
        columns = {}
        for name in frame.columns:
            attr = _FRAME_FIELDS.get(name)
            if attr is not None:
                columns[attr] = name
        for attr, name in _EXTRA_SERIES:
            frame[name] = getattr(self, attr)
            columns[attr] = name
        energy_columns = {}
        for key, values in self.energy.items():
            name = f"energy_{key}_j"
            if name in frame.columns:
                raise InputError(f"energy {key!r}: accepted is a name that does not repeat a column ({name})")
            frame[name] = values
            energy_columns[str(key)] = name
        header = {
            "format": RESULT_FORMAT,
            "version": RESULT_FORMAT_VERSION,
            "columns": columns,
            "energy_columns": energy_columns,
            **{name: getattr(self, name) for name in _SCALARS},
            "segment_t": np.asarray(self.segment_t),
            "nodes": np.asarray(self.nodes),
            "spring_rows": np.asarray(self.spring_rows),
            "springs": [_spring_to_dict(s) for s in self.springs],
            "parameters": _parameters_to_dict(self.parameters),
            "excitation": _excitation_to_dict(self.excitation),
        }

        header["dampersim_version"] = __version__
        text = json.dumps(_to_json(header), allow_nan=False, separators=(",", ":"))
        table = pa.Table.from_pandas(frame, preserve_index=False)
        meta = dict(table.schema.metadata or {})
        meta[_META_KEY] = text.encode("utf-8")
        table = table.replace_schema_metadata(meta)
        return atomic_write(path, lambda tmp: pq.write_table(table, tmp, compression="snappy"), suffix=".parquet.tmp")

    @classmethod
    def load(cls, path) -> "SimulationResult":
        """Read a result written by :meth:`save` (see there for the format and for what
        comes back exactly). A missing, unreadable, foreign or damaged file is an
        InputError naming the file and what is accepted; a Parquet file without the
        ``dampersim.result`` metadata (e.g. from an older ``simulate --out``) holds only
        the time series, which ``pandas.read_parquet`` reads."""

        import pyarrow.parquet as pq

        shown = os.fspath(path)
        accepted = (f"accepted is a Parquet file written by SimulationResult.save "
                    f"({RESULT_FORMAT} version {RESULT_FORMAT_VERSION})")

        def bad(what):
            return InputError(f"result file {shown!r}: {what}; {accepted}")

        if not os.path.isfile(shown):
            raise bad("no such file" if not os.path.exists(shown) else "not a file")
        try:
            pf = pq.ParquetFile(shown, thrift_string_size_limit=2**31 - 1, thrift_container_size_limit=2**31 - 1)
            meta = pf.schema_arrow.metadata or {}
        except OSError as exc:
            raise bad(f"cannot be read as Parquet ({exc})") from None
        except Exception as exc:  # noqa: BLE001 - pyarrow raises ArrowInvalid and others for foreign files
            raise bad(f"is not a Parquet file ({type(exc).__name__}: {exc})") from None
        try:
            return cls._from_parquet(pf, meta, bad)
        finally:
            pf.close()

    @classmethod
    def _from_parquet(cls, pf, meta, bad):
        """The result in an open ``pyarrow.parquet.ParquetFile`` with schema metadata
        ``meta``; ``bad(what)`` makes the InputError naming the file."""

        if _META_KEY not in meta:
            raise bad("has no dampersim.result metadata (only a plain table, e.g. from an older simulate --out)")
        try:
            header = json.loads(meta[_META_KEY].decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as exc:
            raise bad(f"its dampersim.result metadata is not valid JSON ({exc})") from None
        if not isinstance(header, dict) or header.get("format") != RESULT_FORMAT:
            raise bad("its dampersim.result metadata is not a result header")
        if header.get("version") != RESULT_FORMAT_VERSION:
            raise bad(f"format version {header.get('version')!r} is not supported by this dampersim")
        try:
            header = _from_json(header)
            columns = dict(header["columns"])
            energy_columns = dict(header["energy_columns"])
            missing = [a for a in _SERIES_FIELDS if a not in columns]
            if missing:
                raise ValueError(f"no column for {', '.join(missing)}")
            wanted = [columns[a] for a in _SERIES_FIELDS] + list(energy_columns.values())
            table = pf.read(columns=wanted)
            series = {a: _column(table, columns[a]) for a in _SERIES_FIELDS}
            energy = {str(k): _column(table, c) for k, c in energy_columns.items()}
            scalars = {name: _scalar(header[name], name) for name in _SCALARS}
            nodes = _array(header["nodes"], "nodes", ndim=2)
            segment_t = _array(header["segment_t"], "segment_t", ndim=1)
            spring_rows = _array(header["spring_rows"], "spring_rows", ndim=2)
            if len(segment_t) != nodes.shape[0]:
                raise ValueError(f"{len(segment_t)} segment times for {nodes.shape[0]} node frames")
            springs = tuple(_spring_from_dict(d) for d in header["springs"])
            if spring_rows.shape[0] != len(springs):
                raise ValueError(f"{spring_rows.shape[0]} spring rows for {len(springs)} springs")
            excitation = _excitation_from_dict(header["excitation"])
        except Exception as exc:  # noqa: BLE001 - any inconsistency means a damaged file
            raise bad(f"is damaged ({type(exc).__name__}: {exc})") from None
        try:
            parameters = _parameters_from_dict(header["parameters"])
        except (KeyError, DampersimError) as exc:
            raise bad(f"its stored parameter set is not valid ({exc})") from None
        return cls(
            **series,
            energy=energy,
            segment_t=segment_t,
            nodes=nodes,
            springs=springs,
            spring_rows=spring_rows,
            **scalars,
            parameters=parameters,
            excitation=excitation,
        )


# --- file format of SimulationResult.save / load -----------------------------------------
RESULT_FORMAT = "dampersim.result"
RESULT_FORMAT_VERSION = 1
_META_KEY = b"dampersim.result"

#: to_frame column -> field (the table :meth:`SimulationResult.save` writes starts with these)
_FRAME_FIELDS = {
    "time_s": "t",
    "input_torque_nm": "input_torque",
    "output_torque_nm": "output_torque",
    "speed_primary_rad_s": "speed_primary",
    "speed_secondary_rad_s": "speed_secondary",
    "speed_tertiary_rad_s": "speed_tertiary",
    "speed_motor_rad_s": "speed_motor",
    "windup_outer_rad": "windup_outer",
    "windup_inner_rad": "windup_inner",
    "windup_total_rad": "windup_total",
    "hardstop_outer_nm": "hardstop_outer",
    "hardstop_inner_nm": "hardstop_inner",
    "motor_torque_nm": "motor_torque",
}
#: series fields that to_frame leaves out, and their columns
_EXTRA_SERIES = (("spring_torque_outer", "spring_torque_outer_nm"), ("spring_torque_inner", "spring_torque_inner_nm"))
_SERIES_FIELDS = tuple(_FRAME_FIELDS.values()) + tuple(a for a, _ in _EXTRA_SERIES)
_SCALARS = ("speed", "time_step", "sample_rate", "steady_start", "wall_time")


@dataclass(frozen=True)
class ExcitationDescription:
    """What a saved result keeps of an excitation that cannot be rebuilt from a file.

    kind: module and class name of the original object; speed [rad/s]; steady_start [s];
    duration [s] or None (no natural length); text: its repr (at most 2000 characters).
    It has no ``torque(t)``: simulate() refuses it, and the result's ``input_torque``
    series is the torque the original produced.
    """

    kind: str
    speed: float | None
    steady_start: float
    duration: float | None
    text: str


def _to_json(obj):
    """``obj`` as strict-JSON values: numpy arrays as {"$array": {dtype, shape, base64}}
    (little-endian, bit-exact), non-finite floats as {"$float": "nan" | "inf" | "-inf"},
    tuples as lists; floats keep their repr, which reads back to the same double."""

    if isinstance(obj, dict):
        return {str(k): _to_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_to_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind not in "biuf":
            raise InputError(f"array of dtype {obj.dtype}: accepted are numeric arrays")
        le = np.ascontiguousarray(obj, dtype=obj.dtype.newbyteorder("<"))
        return {"$array": {"dtype": le.dtype.str, "shape": list(le.shape),
                           "base64": base64.b64encode(le.tobytes()).decode("ascii")}}
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return {"$float": repr(obj)}
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    raise InputError(f"value {obj!r} of type {type(obj).__name__}: accepted are numbers, text, arrays and lists")


def _from_json(obj):
    """Inverse of :func:`_to_json` (lists stay lists)."""

    if isinstance(obj, list):
        return [_from_json(v) for v in obj]
    if isinstance(obj, dict):
        if set(obj) == {"$array"}:
            d = obj["$array"]
            dtype = np.dtype(d["dtype"])
            if dtype.kind not in "biuf":
                raise ValueError(f"array dtype {dtype} is not numeric")
            shape = tuple(int(n) for n in d["shape"])
            raw = base64.b64decode(d["base64"], validate=True)
            return np.frombuffer(raw, dtype=dtype).reshape(shape).astype(dtype.newbyteorder("="), copy=True)
        if set(obj) == {"$float"}:
            if obj["$float"] not in ("nan", "inf", "-inf"):
                raise ValueError(f"float {obj['$float']!r}")
            return float(obj["$float"])
        return {k: _from_json(v) for k, v in obj.items()}
    return obj


def _tuples(obj):
    return tuple(_tuples(v) for v in obj) if isinstance(obj, list) else obj


def _column(table, name) -> np.ndarray:
    col = table.column(name)
    if col.null_count:
        raise ValueError(f"column {name!r} has missing values")
    return np.array(col.to_numpy(), copy=True)


def _scalar(value, name) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} = {value!r} is not a number")
    return value


def _array(value, name, ndim) -> np.ndarray:
    if not isinstance(value, np.ndarray) or value.ndim != ndim:
        raise ValueError(f"{name} is not a {ndim}-D array")
    return value


def _spring_to_dict(spring) -> dict:
    return {f.name: getattr(spring, f.name) for f in dataclasses.fields(spring)}


def _spring_from_dict(d):
    return SpringInfo(**d)


def _parameters_to_dict(parameters):
    if parameters is None:
        return None
    if not isinstance(parameters, DamperSystem):
        raise InputError(f"parameters of type {type(parameters).__name__}: accepted is a DamperSystem or None")
    return to_dict(parameters)


def _parameters_from_dict(data):
    return None if data is None else system_from_dict(data)


def _excitation_classes() -> dict:
    return {c.__name__: c for c in (OrderSum, TorqueRamp, MeasuredTorque)}


def _excitation_to_dict(excitation):
    """The excitation's fields under its class name when :meth:`SimulationResult.load`
    can rebuild it, else an :class:`ExcitationDescription`'s fields."""

    if excitation is None:
        return None
    kind = type(excitation).__name__
    if _excitation_classes().get(kind) is type(excitation):
        return {"kind": kind, "fields": {f.name: getattr(excitation, f.name) for f in dataclasses.fields(excitation)}}
    if isinstance(excitation, ExcitationDescription):
        desc = excitation
    else:
        def number(name, default):
            try:
                x = float(getattr(excitation, name))
            except (AttributeError, TypeError, ValueError):
                return default
            return x if math.isfinite(x) else default

        cls = type(excitation)
        desc = ExcitationDescription(
            kind=f"{cls.__module__}.{cls.__qualname__}",
            speed=number("speed", None),
            steady_start=number("steady_start", 0.0),
            duration=number("duration", None),
            text=repr(excitation)[:2000],
        )
    return {"kind": "description", "fields": {f.name: getattr(desc, f.name) for f in dataclasses.fields(desc)}}


def _excitation_from_dict(data):
    if data is None:
        return None
    kind, fields = data["kind"], data["fields"]
    if kind == "description":
        return ExcitationDescription(**fields)
    classes = _excitation_classes()
    if kind not in classes:
        raise ValueError(f"excitation kind {kind!r} is none of {', '.join(classes)} or 'description'")
    return classes[kind](**{k: _tuples(v) for k, v in fields.items()})
