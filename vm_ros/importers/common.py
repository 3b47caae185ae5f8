"""What the importers share: source-model muscle parameters -> VM muscle-library entries, the
fibre-type table, and writing geometry file + library + summary into one output folder.

Rules (each written into the library's ``source`` notes; config/muscles.yaml explains 3-5):

- l0 = the source model's optimal fibre length. VM has no pennation angle, so pennation is dropped
  (no cosine factor); the summary counts the muscles pennated more than 5 deg.
- l0t = tendon slack length / LrT (LrT = 0.964 in config/model.yaml): VM's tendon is slack below
  about 0.964 L0T and carries F0 at 1.0 L0T (config/muscles.yaml rule 3).
- mass = F0 * density / specific tension * l0, with F0 the source model's maximum isometric force,
  density VM's (1.06 g/cm^3) and a specific tension chosen on the command line. The default is
  60 N/cm^2, the value Rajagopal et al. 2016 used to turn MRI muscle volumes into forces, so that
  masses come out as measured volumes (their rectus femoris mass is reproduced); VM then computes
  F0 = 31.8 N/cm^2 * mass / (density * l0) = 0.53 of the source model's F0 (both stated in the
  summary). ``--specific-tension vm`` uses VM's own 31.8 N/cm^2 instead: VM's F0 equals the
  model's, and masses (hence energy rates) are 1.9x larger.
- strength (``--strength``): ``vm`` (default) leaves VM's own specific tension to every muscle, as
  above; ``model`` gives each muscle its own ``specific_tension_pa``, the value its mass was made
  with, so that VM's F0 equals the source model's F0 while the mass stays; a number k gives k times
  that value (VM's F0 = k x the model's F0). The entry's source note says which.
- Lmax from the largest sampled path length (the formula of config/muscles.yaml rule 4; that
  rule resets an out-of-band value to 1.3 for the shipped library, while the importer keeps the
  band's end nearest the geometry), clipped into VM's
  1.1-1.4 (the geometric value quoted in the source note); the library gets the path_length_max_m
  that gives the clipped Lmax.
- path_length_min_m: the smallest sampled path length, clipped to the path giving L = 0.6 where it
  would be shorter (rule 5).
- fpcsa_slow from config/fibre_types.yaml by muscle name, else a stated default (0.5), counted.
"""

from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from vm_ros.errors import ConfigError, VmRosError
from vm_ros.geometry.file import write_geometry
from vm_ros.model.mechanics import lmax_from_path_length_max
from vm_ros.model.params import load_model_params
from vm_ros.resources import config_dir

LMAX_BAND = (1.1, 1.4)                 # VM's valid Lmax (L0), config/muscles.yaml rule 4
PENNATION_REPORTED_RAD = math.radians(5.0)
MIN_FASCICLE_L0 = 0.6                  # rule 5: shortest fascicle length kept (L0)
MIN_TENDON_L0T = 0.97                  # rule 5: tendon length assumed at the shortest path (L0T)
RAJAGOPAL_SPECIFIC_TENSION_PA = 60e4   # 60 N/cm^2, Rajagopal et al. 2016
LENGTH_WARNING_M = 1e-3                # held-out length RMS reported loudly above this
_SIDE_SUFFIX = re.compile(r"_(r|l)$", re.IGNORECASE)


@dataclass(frozen=True)
class ImportedMuscle:
    """One muscle's parameters as the source model gives them (SI).

    | field | unit | meaning |
    | --- | --- | --- |
    | f0_n | N | maximum isometric force of the source model |
    | l0_m | m | optimal fibre length |
    | tendon_slack_m | m | tendon slack length |
    | path_length_min_m, path_length_max_m | m | extremes over the sampled poses |
    | pennation_rad | rad | pennation angle at optimal fibre length (dropped by VM) |
    """

    name: str
    f0_n: float
    l0_m: float
    tendon_slack_m: float
    path_length_min_m: float
    path_length_max_m: float
    pennation_rad: float = 0.0
    note: str = ""


@dataclass(frozen=True)
class SpecificTension:
    """The specific tension used to turn a model's F0 into a mass, and where it comes from."""

    pa: float
    source: str

    @property
    def n_per_cm2(self) -> float:
        return self.pa / 1e4


@dataclass(frozen=True)
class Strength:
    """``--strength``: VM's F0 as a multiple of the source model's F0 (``factor``), or None for
    VM's own specific tension (config/model.yaml) on every muscle."""

    factor: float | None = None

    @property
    def word(self) -> str:
        if self.factor is None:
            return "vm"
        return "model" if self.factor == 1.0 else f"{self.factor:g}"


def strength_option(text: str) -> Strength:
    """``--strength``: ``vm``, ``model`` (keep the source model's F0) or a factor in 0.1-10."""
    word = str(text).strip().lower()
    if word in ("vm", "model"):
        return Strength(None if word == "vm" else 1.0)
    try:
        value = float(word)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and 0.1 <= value <= 10.0):
        raise VmRosError(f"--strength {text!r}: give 'vm', 'model' or a factor of the model's F0 "
                         "in 0.1-10")
    return Strength(value)


def specific_tension_option(text: str, params=None) -> SpecificTension:
    """``--specific-tension``: a number in N/cm^2, ``rajagopal`` (60 N/cm^2) or ``vm`` (VM's
    own value from config/model.yaml, which keeps VM's F0 equal to the source model's)."""
    word = str(text).strip().lower()
    if word == "vm":
        g = (params or load_model_params()).generic
        return SpecificTension(g.specific_tension, f"VM's own {g.specific_tension / 1e4:g} N/cm^2 "
                               "(config/model.yaml, Cheng 2000): VM's F0 equals the model's F0")
    if word in ("rajagopal", "60"):
        return SpecificTension(RAJAGOPAL_SPECIFIC_TENSION_PA, "60 N/cm^2 of Rajagopal et al. "
                               "2016, who made forces from MRI muscle volumes with it: masses "
                               "come out as the measured volumes times density")
    try:
        value = float(word)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and 5.0 <= value <= 200.0):
        raise VmRosError(f"--specific-tension {text!r}: give N/cm^2 in 5-200, 'rajagopal' (60) "
                         "or 'vm'")
    return SpecificTension(value * 1e4, f"{value:g} N/cm^2 (given with --specific-tension)")


# ---------------------------------------------------------------------------- fibre types


def name_stem(name: str) -> str:
    """A muscle name as the fibre table matches it: side suffix (_r, _l) removed, lower case."""
    return _SIDE_SUFFIX.sub("", str(name)).lower()


def load_fibre_table(path=None) -> dict:
    """config/fibre_types.yaml as ``{"default": {fpcsa_slow, source}, "names": {stem: {fpcsa_slow,
    source, entry}}, "path": str}``; ConfigError on a malformed file."""
    path = Path(path) if path is not None else config_dir() / "fibre_types.yaml"
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(path, "<file>", None, f"cannot read: {exc.strerror or exc}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(path, "<file>", None, "not valid YAML") from exc
    if not isinstance(data, dict) or data.get("format") != "vm_ros.fibre_types":
        raise ConfigError(path, "format", None, "expected 'vm_ros.fibre_types'")
    default = data.get("default") or {}
    names: dict[str, dict] = {}
    table = {"default": {"fpcsa_slow": _fraction(path, "default.fpcsa_slow",
                                                 default.get("fpcsa_slow")),
                         "source": str(default.get("source", ""))},
             "names": names, "path": str(path)}
    for key, entry in (data.get("muscles") or {}).items():
        if not isinstance(entry, dict) or not entry.get("source"):
            raise ConfigError(path, f"muscles.{key}", entry, "need fpcsa_slow, names, source")
        value = _fraction(path, f"muscles.{key}.fpcsa_slow", entry.get("fpcsa_slow"))
        for alias in entry.get("names") or [key]:
            stem = name_stem(alias)
            if stem in names:
                raise ConfigError(path, f"muscles.{key}.names", alias,
                                  f"already listed under {names[stem]['entry']}")
            names[stem] = {"fpcsa_slow": value, "source": str(entry["source"]), "entry": key}
    return table


def _fraction(path, field, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 1:
        raise ConfigError(path, field, value, "must be a fraction in [0, 1]")
    return float(value)


def fibre_fraction(table: dict, name: str, default=None) -> tuple[float, str, bool]:
    """(fpcsa_slow, source note, found in the table) for a muscle name."""
    hit = table["names"].get(name_stem(name))
    if hit is not None:
        return hit["fpcsa_slow"], (f"{hit['source']}; fibre-number fraction used as PCSA "
                                   f"fraction (config/fibre_types.yaml entry {hit['entry']})"), True
    value = table["default"]["fpcsa_slow"] if default is None else float(default)
    return value, f"default {value:g}: {table['default']['source']}", False


# ---------------------------------------------------------------------------- library entries


def library_entries(muscles, *, specific_tension_pa, density_kg_per_m3, fibre_table,
                    default_fpcsa_slow, ur, params=None, origin="the source model",
                    strength: Strength = Strength()) -> tuple[dict, list[dict]]:
    """VM muscle-library fields for imported muscles, and one summary row per muscle.

    Returns (``{name: {mass_kg, l0_m, l0t_m, path_length_max_m, path_length_min_m, fpcsa_slow,
    ur, source: {field: note}, description}}``, rows). ``params``: VM's ModelParams (default the
    shipped config/model.yaml), whose LrT, tendon and PE1 constants and specific tension enter
    rules 3-4 and the VM F0 reported in the rows. ``origin`` names the model in the notes.
    ``strength``: with a factor, each entry gets ``specific_tension_pa`` = factor * the specific
    tension of its mass, so that VM's F0 = factor * the model's F0.
    """
    g = (params or load_model_params()).generic
    sigma = float(specific_tension_pa)
    entries, rows = {}, []
    for m in muscles:
        l0, f0 = float(m.l0_m), float(m.f0_n)
        if not (l0 > 0 and f0 > 0 and m.tendon_slack_m > 0 and m.path_length_max_m > 0):
            raise VmRosError(f"muscle {m.name!r}: need positive F0, optimal fibre length, tendon "
                             "slack length and path length; got "
                             f"F0 {f0}, l0 {l0}, slack {m.tendon_slack_m}, "
                             f"path max {m.path_length_max_m}")
        l0t = float(m.tendon_slack_m) / g.lrt
        mass = f0 * density_kg_per_m3 * l0 / sigma
        own = None if strength.factor is None else strength.factor * sigma
        f0_vm = (g.specific_tension if own is None else own) * mass / (g.muscle_density * l0)
        lmax_geometric = float(lmax_from_path_length_max(m.path_length_max_m, l0, l0t, g))
        lmax = min(max(lmax_geometric, LMAX_BAND[0]), LMAX_BAND[1])
        # Lmax is linear in the path length: shift the path by the clipped fascicle excursion.
        path_max = float(m.path_length_max_m) + (lmax - lmax_geometric) * l0
        shortest = MIN_TENDON_L0T * l0t + MIN_FASCICLE_L0 * l0
        path_min = max(float(m.path_length_min_m), shortest)
        fpcsa_slow, fibre_note, fibre_found = fibre_fraction(fibre_table, m.name,
                                                             default_fpcsa_slow)
        pennation_deg = math.degrees(m.pennation_rad)
        penn_note = (f"; pennation {pennation_deg:.1f} deg at l0 dropped (VM has none)"
                     if m.pennation_rad > 0 else "")
        lmax_note = (f"largest sampled path length {m.path_length_max_m:.5f} m -> Lmax "
                     f"{lmax_geometric:.3f} (config/muscles.yaml rule 4)")
        if lmax != lmax_geometric:
            lmax_note += (f", outside VM's {LMAX_BAND[0]}-{LMAX_BAND[1]}: clipped to "
                          f"Lmax {lmax:.2f}, i.e. path_length_max_m = {path_max:.5f} m")
        min_note = f"smallest sampled path length {m.path_length_min_m:.5f} m"
        if path_min != float(m.path_length_min_m):
            min_note += (f" gives L < {MIN_FASCICLE_L0} L0 (slack); clipped to the path giving "
                         f"L = {MIN_FASCICLE_L0}: {MIN_TENDON_L0T}*l0t_m + "
                         f"{MIN_FASCICLE_L0}*l0_m (config/muscles.yaml rule 5)")
        if path_min > path_max:
            min_note += ("; above path_length_max_m after the Lmax clip: the model's tendon "
                         "slack and fibre lengths do not span this path's excursion")
        entries[m.name] = {
            "mass_kg": _round(mass), "l0_m": _round(l0), "l0t_m": _round(l0t),
            "path_length_max_m": _round(path_max), "path_length_min_m": _round(path_min),
            "fpcsa_slow": _round(fpcsa_slow), "ur": float(ur),
            "source": {
                "mass_kg": (f"{origin}: F0 {f0:.6g} N * density {density_kg_per_m3:g} kg/m^3 * "
                            f"l0 / specific tension {sigma / 1e4:g} N/cm^2; VM's F0 is then "
                            f"{f0_vm:.6g} N"),
                "l0_m": f"{origin}: optimal fibre length {l0:.6g} m{penn_note}",
                "l0t_m": (f"{origin}: tendon slack length {m.tendon_slack_m:.6g} m; L0T = Ls / "
                          f"{g.lrt:g} (config/muscles.yaml rule 3)"),
                "path_length_max_m": f"{origin}: {lmax_note}",
                "path_length_min_m": f"{origin}: {min_note}",
                "fpcsa_slow": fibre_note,
                "ur": f"{float(ur):g}: VM default (Cheng 2000; Tsianos 2012)",
            },
            "description": m.note or f"imported from {origin}",
        }
        if own is not None:
            entries[m.name]["specific_tension_pa"] = _round(own)
            entries[m.name]["source"]["specific_tension_pa"] = (
                f"--strength {strength.word}: {strength.factor:g} x the {sigma / 1e4:g} N/cm^2 "
                f"the mass was made with, so that VM's F0 = {strength.factor:g} x {origin}'s F0 "
                f"{f0:.6g} N")
        rows.append({"name": m.name, "f0_model_n": f0, "f0_vm_n": f0_vm, "mass_kg": mass,
                     "l0_m": l0, "l0t_m": l0t, "lmax_geometric": lmax_geometric, "lmax": lmax,
                     "fpcsa_slow": fpcsa_slow, "fibre_found": fibre_found,
                     "pennation_deg": pennation_deg})
    return entries, rows


def _round(value: float) -> float:
    """Library numbers to 9 significant digits: far below the sources' own precision, and
    close enough that the clipped Lmax stays inside VM's band to 1e-8."""
    return float(f"{float(value):.9g}")


def write_library(path, entries: dict, header: str) -> Path:
    """Write a muscle-library YAML (``muscles:`` mapping) with ``header`` as comment lines above
    it; MuscleBank.from_config(library=path) loads it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    comments = "".join(f"# {line}".rstrip() + "\n" for line in header.splitlines())
    body = yaml.safe_dump({"muscles": entries}, sort_keys=False, width=100, allow_unicode=True)
    path.write_text(comments + "\n" + body, encoding="utf-8")
    return path


def choices_text(rows, *, specific_tension: SpecificTension, density_kg_per_m3, fibre_table,
                 params=None, strength: Strength = Strength()) -> str:
    """The parameter choices and their consequences, as lines (summary and library header)."""
    g = (params or load_model_params()).generic
    n = len(rows)
    ratio = g.specific_tension / specific_tension.pa
    pennated = [r["name"] for r in rows if math.radians(r["pennation_deg"])
                > PENNATION_REPORTED_RAD]
    clipped = [r for r in rows if r["lmax"] != r["lmax_geometric"]]
    defaults = [r["name"] for r in rows if not r["fibre_found"]]
    lines = [
        f"mass = F0 * density {density_kg_per_m3:g} kg/m^3 * l0 / specific tension "
        f"{specific_tension.n_per_cm2:g} N/cm^2 ({specific_tension.source}).",
        (f"VM computes F0 = {g.specific_tension / 1e4:g} N/cm^2 * mass / (density * l0): "
         f"VM F0 = {ratio:.3g} x the model's F0" if strength.factor is None else
         f"--strength {strength.word}: each muscle's specific_tension_pa is "
         f"{strength.factor * specific_tension.n_per_cm2:g} N/cm^2, so VM F0 = "
         f"{strength.factor:g} x the model's F0")
        + f" (total {sum(r['f0_vm_n'] for r in rows):.0f} N "
        f"vs {sum(r['f0_model_n'] for r in rows):.0f} N).",
        f"l0 = optimal fibre length; pennation dropped (VM has none): {len(pennated)} of {n} "
        "muscles pennated more than 5 deg"
        + (f" ({_names(pennated)})." if pennated else "."),
        f"l0t = tendon slack length / {g.lrt:g} (config/muscles.yaml rule 3).",
        f"Lmax from the largest sampled path length (rule 4), clipped into VM's "
        f"{LMAX_BAND[0]}-{LMAX_BAND[1]}: {len(clipped)} of {n} clipped"
        + (f" (geometric {min(r['lmax_geometric'] for r in clipped):.2f}-"
           f"{max(r['lmax_geometric'] for r in clipped):.2f})." if clipped else "."),
        f"fpcsa_slow from {fibre_table['path']}: {n - len(defaults)} of {n} muscles found; "
        f"{len(defaults)} given the default"
        + (f" ({_names(defaults)})." if defaults else "."),
    ]
    return "\n".join(lines)


def _names(names, most: int = 12) -> str:
    names = list(names)
    shown = ", ".join(names[:most])
    return shown + (f", ... ({len(names) - most} more)" if len(names) > most else "")


def print_summary(rows, file=None) -> None:
    """Per-muscle parameter table: model F0, VM F0, mass, l0, l0t, Lmax (geometric and used),
    fpcsa_slow (* = default), pennation."""
    file = file or sys.stdout
    print(f"{'muscle':<16} {'F0 model':>9} {'F0 VM':>8} {'mass':>7} {'l0':>6} {'l0t':>6} "
          f"{'Lmax geo':>8} {'Lmax':>5} {'slow':>6} {'penn':>5}", file=file)
    print(f"{'':<16} {'N':>9} {'N':>8} {'g':>7} {'mm':>6} {'mm':>6} {'L0':>8} {'L0':>5} "
          f"{'':>6} {'deg':>5}", file=file)
    for r in rows:
        print(f"{r['name']:<16} {r['f0_model_n']:9.1f} {r['f0_vm_n']:8.1f} "
              f"{r['mass_kg'] * 1e3:7.1f} {r['l0_m'] * 1e3:6.1f} {r['l0t_m'] * 1e3:6.1f} "
              f"{r['lmax_geometric']:8.3f} {r['lmax']:5.2f} "
              f"{r['fpcsa_slow']:5.3f}{' ' if r['fibre_found'] else '*'} "
              f"{r['pennation_deg']:5.1f}", file=file)


def print_fit_table(geometry, file=None, length_warning_m: float = LENGTH_WARNING_M) -> int:
    """Per-muscle fit table (coordinates, degree, held-out length RMS/max and moment-arm RMS in
    mm, flags); muscles whose held-out length RMS exceeds ``length_warning_m`` or that carry
    flags are listed again, loudly, below it. Returns how many were listed."""
    file = file or sys.stdout
    print(f"{'muscle':<16} {'deg':>3} {'L rms':>7} {'L max':>7} {'r rms':>7}  "
          "coordinates / flags", file=file)
    print(f"{'':<16} {'':>3} {'mm':>7} {'mm':>7} {'mm':>7}", file=file)
    bad = []
    for m in geometry.muscles:
        fit = m.fit
        degree = int(m.exponents.sum(axis=1).max(initial=0))
        if fit is None:
            print(f"{m.name:<16} {degree:3d} {'-':>7} {'-':>7} {'-':>7}  "
                  f"{', '.join(m.coordinates)}", file=file)
            continue
        flags = f"  [{', '.join(fit.flags)}]" if fit.flags else ""
        print(f"{m.name:<16} {degree:3d} {fit.length_rms_m * 1e3:7.3f} "
              f"{fit.length_max_m * 1e3:7.3f} {fit.moment_arm_rms_m * 1e3:7.3f}  "
              f"{', '.join(m.coordinates)}{flags}", file=file)
        if fit.length_rms_m > length_warning_m or fit.flags:
            bad.append((m, fit))
    lengths = [m.fit.length_rms_m * 1e3 for m in geometry.muscles if m.fit is not None]
    if lengths:
        print(f"held-out length RMS: median {np.median(lengths):.4f} mm, worst "
              f"{max(lengths):.4f} mm over {len(lengths)} muscles", file=file)
    if bad:
        print(f"WARNING: {len(bad)} muscle(s) fit poorly (held-out length RMS above "
              f"{length_warning_m * 1e3:g} mm) or are flagged; they are written with their fit "
              "report, check before use:", file=file)
        for m, fit in bad:
            why = ", ".join(fit.flags) or "poor fit"
            print(f"  !! {m.name}: length RMS {fit.length_rms_m * 1e3:.3f} mm, max "
                  f"{fit.length_max_m * 1e3:.3f} mm over {', '.join(m.coordinates)} ({why})",
                  file=file)
    return len(bad)


@dataclass(frozen=True)
class ImportChoices:
    """Command-line choices that turn source parameters into library entries."""

    specific_tension: SpecificTension
    default_fpcsa_slow: float | None = None
    ur: float = 0.8
    strength: Strength = Strength()


@dataclass(frozen=True)
class FitOptions:
    """How an importer samples and fits (both import verbs' options; recorded in the geometry
    file by ``recorded``). VmRosError naming the option for a bad value."""

    degree: int = 6
    samples: int = 1000
    held_out: int | None = None           # default max(50, samples // 4)
    length_tolerance_m: float = 2e-5
    seed: int = 0
    muscles: tuple = ()                   # import only these (default: all)
    max_terms: int = 500                  # largest polynomial tried per muscle (terms)

    def __post_init__(self):
        if not 1 <= self.degree <= 10:
            raise VmRosError(f"--degree {self.degree}: give 1-10")
        if self.samples < 10:
            raise VmRosError(f"--samples {self.samples}: give at least 10")
        if self.held_out is not None and self.held_out < 5:
            raise VmRosError(f"--held-out {self.held_out}: give at least 5")
        if not self.length_tolerance_m > 0:
            raise VmRosError("--tolerance-mm must be > 0")
        if self.max_terms < 1:
            raise VmRosError(f"--max-terms {self.max_terms}: give at least 1")

    @property
    def n_held_out(self) -> int:
        return self.held_out if self.held_out is not None else max(50, self.samples // 4)

    def degrees(self, n_coordinates: int) -> tuple[int, ...]:
        """Total degrees tried for a muscle crossing n coordinates: 2 (or --degree) up to
        --degree, as long as the polynomial has at most max_terms terms (C(d + n, n)); at least
        the lowest. The cost of a least-squares fit grows with the square of the terms: a tendon
        crossing 8 finger joints at degree 6 has 3003 of them (30 s per fit)."""
        low = min(2, self.degree)
        kept = [d for d in range(low, self.degree + 1)
                if math.comb(d + n_coordinates, n_coordinates) <= self.max_terms]
        return tuple(kept) or (low,)

    def recorded(self) -> dict:
        """The options as the geometry file's ``options`` record them."""
        return {"degree_max": self.degree, "max_terms": self.max_terms,
                "length_tolerance_m": self.length_tolerance_m, "samples_fit": self.samples,
                "samples_held_out": self.n_held_out, "seed": self.seed}


def add_fit_arguments(parser) -> None:
    """--degree, --samples, --held-out, --tolerance-mm (both import verbs)."""
    parser.add_argument("--degree", type=int, default=6,
                        help="highest total polynomial degree tried (default 6)")
    parser.add_argument("--samples", type=int, default=1000,
                        help="fitted poses (default 1000; held-out: a quarter, at least 50)")
    parser.add_argument("--held-out", type=int, default=None, help="held-out poses")
    parser.add_argument("--tolerance-mm", type=float, default=0.02,
                        help="held-out length RMS at which a lower degree is accepted "
                             "(default 0.02 mm)")


def add_parameter_arguments(parser) -> None:
    """--specific-tension, --fibre-default, --ur (both import verbs); see ``choices_from_args``."""
    parser.add_argument("--specific-tension", default="rajagopal", metavar="N_PER_CM2",
                        help="mass = F0 * density * l0 / this: N/cm^2, 'rajagopal' (60, the "
                             "default: masses as measured volumes) or 'vm' (VM's 31.8: VM's F0 "
                             "equals the model's)")
    parser.add_argument("--fibre-default", type=float, default=None, metavar="FRACTION",
                        help="fpcsa_slow for muscles without fibre-type data (default 0.5, "
                             "config/fibre_types.yaml)")
    parser.add_argument("--ur", type=float, default=0.8,
                        help="drive at which all units are recruited (default 0.8)")
    parser.add_argument("--strength", default="vm", metavar="vm|model|FACTOR",
                        help="VM's F0: 'vm' (the default: VM's own specific tension, 31.8 "
                             "N/cm^2, on the masses), 'model' (each muscle keeps the source "
                             "model's F0, through its own specific_tension_pa) or a factor of "
                             "the model's F0")


def choices_from_args(args) -> ImportChoices:
    """ImportChoices from the ``add_parameter_arguments`` options; VmRosError on a bad value."""
    if args.fibre_default is not None and not 0 <= args.fibre_default <= 1:
        raise VmRosError(f"--fibre-default {args.fibre_default}: give a fraction in [0, 1]")
    if not 0 < args.ur <= 1:
        raise VmRosError(f"--ur {args.ur}: give a value in (0, 1]")
    return ImportChoices(specific_tension_option(args.specific_tension), args.fibre_default,
                         args.ur, strength_option(args.strength))


def write_import(out_dir, geometry, muscles, choices: ImportChoices, *, title: str,
                 origin: str, params=None, fibre_table=None, file=None) -> dict:
    """Write DIR/geometry.yaml, DIR/muscles.yaml and DIR/summary.txt, and print the summary.

    ``title``: the first lines of the library header (which model, which importer); ``origin``
    names the model in each source note. Returns the paths written.
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise VmRosError(f"--out {out}: cannot make the folder ({exc.strerror or exc})") from None
    params = params or load_model_params()
    table = fibre_table or load_fibre_table()
    density = params.generic.muscle_density
    entries, rows = library_entries(
        muscles, specific_tension_pa=choices.specific_tension.pa, density_kg_per_m3=density,
        fibre_table=table, default_fpcsa_slow=choices.default_fpcsa_slow, ur=choices.ur,
        params=params, origin=origin, strength=choices.strength)
    text = choices_text(rows, specific_tension=choices.specific_tension,
                        density_kg_per_m3=density, fibre_table=table, params=params,
                        strength=choices.strength)
    header = "\n".join([title, "", "Parameter rules (vm_ros.importers.common, docs/geometry.md):",
                        *text.splitlines(), "",
                        "Geometry (path lengths, moment arms) is in geometry.yaml beside this "
                        "file."])
    summary = out / "summary.txt"
    try:
        paths = {"geometry": write_geometry(geometry, out / "geometry.yaml"),
                 "library": write_library(out / "muscles.yaml", entries, header)}
        handle = open(summary, "w", encoding="utf-8")  # noqa: SIM115 - closed by the with below
    except OSError as exc:
        raise VmRosError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    with handle:
        for stream in (handle, file or sys.stdout):
            print(title, file=stream)
            print(file=stream)
            print_fit_table(geometry, stream)
            print(file=stream)
            print_summary(rows, stream)
            print("(* fpcsa_slow is the default: no fibre-type data for that name)", file=stream)
            print(file=stream)
            print(text, file=stream)
            print(f"\nwrote {paths['geometry']}, {paths['library']}, {summary}", file=stream)
    paths["summary"] = summary
    return paths


__all__ = ["ImportChoices", "ImportedMuscle", "LMAX_BAND", "SpecificTension", "Strength",
           "strength_option",
           "add_fit_arguments", "add_parameter_arguments", "choices_from_args", "choices_text",
           "fibre_fraction", "library_entries", "load_fibre_table", "name_stem", "print_fit_table",
           "print_summary", "specific_tension_option", "write_import", "write_library"]
