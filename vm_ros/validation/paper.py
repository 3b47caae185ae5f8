"""Validation against Tsianos, Rustin & Loeb 2012: the paper's figures as checks.

A check computes what the model gives for one of the paper's claims, compares it with explicit
criteria (numbers, signs, orderings, ratios) and returns a :class:`CheckResult`; ``plot`` draws
the figure. ``vm-ros validate`` runs them all, writes one PNG per figure and a CSV of the numbers.
The tests in test/test_validation.py assert the same criteria.

Energy is converted to muscle temperature rate with the heat capacity 3.75 kJ/(kg K):
dT/dt = energy rate / (wet mass * c). Figs. 5 and 6 compare the initial energy rate (E_a + E_xb)
with the measured heat, as the paper does, and report the total (with recovery) beside it.
"""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

from vm_ros.model import MuscleBank, load_model_params
from vm_ros.model.curves import fibre_type_curves, tendon_length_at_force
from vm_ros.model.layout import type_columns
from vm_ros.model.lumped_fit import compare_sinusoidal, compare_steady, with_drive_law
from vm_ros.model.params import FAST, SLOW, resolve_muscles
from vm_ros.validation.results import CheckResult, Criterion

DT = 1e-3


def _path_for(bank: MuscleBank, l=1.0, force_f0=0.5):
    g = bank.params.generic
    return bank.l0_m * l + bank.l0t_m * tendon_length_at_force(force_f0, g.ct, g.kt, g.lrt)


def isometric_at(bank: MuscleBank, drive, l=1.0, iterations=4):
    """Steady isometric state with every fascicle at ``l`` L0: the path is re-placed for the
    tendon force actually carried."""
    lp = _path_for(bank, l, 0.5)
    g = bank.params.generic
    for _ in range(iterations):
        out = bank.reset(lp, excitation=drive)
        f = np.maximum(out.force / bank.f0, 1e-4)
        lp = bank.l0_m * l + bank.l0t_m * tendon_length_at_force(f, g.ct, g.kt, g.lrt)
    return bank.reset(lp, excitation=drive)


def _isovelocity(bank: MuscleBank, drive, v_l0_per_s, settle_s=0.15, l_mid=1.0):
    """Drive held, path moving so that the fascicle passes L = l_mid at constant velocity V:
    returns the output when the fascicle crosses l_mid (after the force has settled)."""
    lp_mid = _path_for(bank, l_mid, 0.5)
    vp = v_l0_per_s * bank.l0_m
    steps = int(round(settle_s / DT))
    lp0 = lp_mid - vp * settle_s
    bank.reset(lp0, excitation=drive)
    out = None
    for k in range(steps):
        out = bank.step(DT, drive, lp0 + k * DT * vp, vp)
    return out


def _pure_fibre_banks(params):
    """(fibre index, name, bank) for a 100 % slow and a 100 % fast vastus lateralis."""
    for t, name in ((SLOW, "slow"), (FAST, "fast")):
        yield t, name, MuscleBank.from_config(
            ["vastus_lateralis"], params=params,
            overrides={"vastus_lateralis": {"fpcsa_slow": 1.0 - t}})


# --- item 1: Fig. 2 ---------------------------------------------------------------------------


def check_fig2_energy_velocity(params=None) -> CheckResult:
    """Tetanic energy rate vs velocity at L0 for 100 % slow and 100 % fast muscle (Barclay)."""
    params = params or load_model_params()
    e = params.energetics
    result = CheckResult("1", "Fig. 2: tetanic energy-velocity at L0",
                         "initial energy vs velocity equals Barclay 1996; E_a is 30-40 % of E_i "
                         "isometric; E_a does not depend on velocity or length")
    velocities = np.linspace(-6.0, 0.6, 34)
    for t, name, bank in _pure_fibre_banks(params):
        iso = isometric_at(bank, [1.0])
        act0 = float(iso.effective_activation[0, t])
        model, e_act, realised = [], [], []
        for v in velocities:
            out = _isovelocity(bank, [1.0], v)
            realised.append(out.velocity_l0_per_s[0])
            dry = e.dry_to_wet_mass * bank.mass_kg[0]
            acteff = out.effective_activation[0, t]
            # per kg dry and per unit activation, at the FL of the instant (close to 1)
            fl = fibre_type_curves(out.length_l0[0], 0.0, type_columns(params.fibre.take(t)),
                                   params.generic.fv_denominator_min)[0]
            r = out.energy_rate_by_fibre
            model.append((r.activation[0, t] / act0 + r.cross_bridge[0, t] / (acteff * fl)) / dry)
            e_act.append(r.activation[0, t])
        # compare at the fascicle velocity actually realised (the tendon takes up some motion)
        v_real = np.array(realised)
        v_short = np.minimum(v_real, 0.0)
        barclay = (e.e1[t] * v_short**2 + e.e2[t] * v_short + e.e3[t]) / (e.e4[t] - v_short)
        model = np.array(model)
        shortening = v_real <= 0
        err = np.max(np.abs(model[shortening] - barclay[shortening]) / barclay[shortening])
        result.criteria.append(Criterion(f"{name}: max relative deviation from Barclay (V<=0)",
                                         float(err), None, 0.01))
        e_i0 = iso.energy_rate.activation[0] + iso.energy_rate.cross_bridge[0]
        result.criteria.append(Criterion(f"{name}: E_a / E_i isometric tetanic",
                                         float(iso.energy_rate.activation[0] / e_i0), 0.30, 0.40))
        spread = np.ptp(e_act) / np.mean(e_act)
        result.criteria.append(Criterion(f"{name}: relative spread of E_a over velocity",
                                         float(spread), None, 1e-6))
        result.data[name] = {"velocity": v_real, "model": model, "barclay": barclay,
                             "e_a_per_kg_dry": np.array(e_act) / (act0 * dry)}
    return result


# --- item 2: Fig. 3 ---------------------------------------------------------------------------


def _initial_w(out):
    """Initial energy rate E_a + E_xb (W): the total without recovery."""
    return out.energy_rate.activation + out.energy_rate.cross_bridge


def check_fig3_fibre_type_energy(params=None) -> CheckResult:
    params = params or load_model_params()
    result = CheckResult("2", "Fig. 3: energy vs drive, velocity and length, slow vs fast",
                         "fast fibres can consume more than five times as much energy per unit "
                         "time as slow fibres for the same force (initial energy); energy rises "
                         "with drive and shortening speed, falls on both sides of L0 "
                         "asymmetrically; E_a constant across V and L")
    per_newton, per_newton_total, curves = {}, {}, {}
    for t, name, bank in _pure_fibre_banks(params):
        drives = np.linspace(0.1, 1.0, 10)
        by_drive = [isometric_at(bank, [u]) for u in drives]
        force = np.array([o.force[0] for o in by_drive])
        per_newton[name] = np.array([_initial_w(o)[0] for o in by_drive]) / force
        per_newton_total[name] = np.array([o.energy_rate.total[0] for o in by_drive]) / force
        lengths = np.round(np.linspace(0.6, 1.4, 9), 3)
        by_length = [isometric_at(bank, [1.0], l=l) for l in lengths]
        velocities = np.array([-4.0, -2.0, -1.0, -0.5, 0.0])
        by_velocity = [_isovelocity(bank, [1.0], v) for v in velocities]
        curves[name] = {
            "drive": drives, "e_a_drive": [o.energy_rate.activation[0] for o in by_drive],
            "e_xb_drive": [o.energy_rate.cross_bridge[0] for o in by_drive],
            "length": lengths, "total_length": [o.energy_rate.total[0] for o in by_length],
            "initial_length": [_initial_w(o)[0] for o in by_length],
            "e_a_length": [o.energy_rate.activation[0] for o in by_length],
            "e_xb_length": [o.energy_rate.cross_bridge[0] for o in by_length],
            "fl_length": fibre_type_curves(lengths, 0.0, type_columns(params.fibre.take(t)),
                                           params.generic.fv_denominator_min)[0],
            "velocity": velocities, "total_velocity": [o.energy_rate.total[0] for o in by_velocity],
            "initial_velocity": [_initial_w(o)[0] for o in by_velocity],
            "e_a_velocity": [o.energy_rate.activation[0] for o in by_velocity],
            "mass_kg": bank.mass_kg[0]}
    ratio = per_newton["fast"] / per_newton["slow"]
    ratio_total = per_newton_total["fast"] / per_newton_total["slow"]
    # The paper's "more than five times" is a statement on the initial energy (E_a + E_xb, the
    # partition of its section II), hence >= 5 on initial energy, at every drive.
    result.criteria.append(Criterion("fast/slow initial energy per newton, isometric (min over "
                                     "drive 0.1-1)", float(ratio.min()), 5.0, None))
    # Beside it, the total with static recovery, reported and not held: recovery is R x initial
    # with R = 1.5 (slow) / 1.0 (fast), so this ratio is the initial one x 2 / 2.5; the paper's
    # claim is not about it.
    result.criteria.append(Criterion("fast/slow total energy per newton, with recovery (min; "
                                     "reported)", float(ratio_total.min()), None, None))
    for name, c in curves.items():
        result.criteria.append(Criterion(f"{name}: E_a and E_xb rise with drive (min step, W)",
                                         float(min(np.diff(c["e_a_drive"]).min(),
                                                   np.diff(c["e_xb_drive"]).min())), 0.0, None))
        result.criteria.append(Criterion(f"{name}: total at -4 L0/s / isometric",
                                         c["total_velocity"][0] / c["total_velocity"][-1],
                                         1.5, None))
        tl = np.array(c["total_length"])
        lengths = list(c["length"])
        peak = int(np.argmax(tl))
        result.criteria.append(Criterion(f"{name}: L of peak energy (L0)",
                                         float(c["length"][peak]), 0.85, 1.2))
        at_l0 = tl[lengths.index(1.0)]
        short, long = tl[lengths.index(0.7)], tl[lengths.index(1.3)]
        result.criteria.append(Criterion(f"{name}: energy at 0.7 and 1.3 L0 / at L0 (max)",
                                         float(max(short, long) / at_l0), None, 0.99))
        result.criteria.append(Criterion(f"{name}: asymmetry |E(0.7) - E(1.3)| / E(L0)",
                                         float(abs(short - long) / at_l0), 0.01, None))
        # the cross-bridge energy peaks where FL does (Af's length dependence shifts it little)
        xb_peak = float(c["length"][int(np.argmax(c["e_xb_length"]))])
        result.criteria.append(Criterion(f"{name}: L of peak cross-bridge energy (L0; FL peak 1)",
                                         xb_peak, 0.9, 1.1))
        spread = max(np.ptp(c["e_a_length"]), np.ptp(c["e_a_velocity"])) / c["e_a_length"][0]
        result.criteria.append(Criterion(f"{name}: relative spread of E_a across V and L",
                                         float(spread), None, 1e-6))
    result.data = {"per_newton": per_newton, "per_newton_total": per_newton_total,
                   "curves": curves}
    return result


# --- item 3: Fig. 4 ---------------------------------------------------------------------------


def without_yield(params):
    """``params`` with the yield effect disabled. Yield enters the activation-frequency relation
    through a factor that relaxes (time constant ty) towards 1 - cy (1 - exp(-|V| / vy)), cy 0.35
    for slow fibres and 0 (neutral) for fast ones; cy = 0 for both makes that target 1 at every
    velocity, so the factor stays at 1 (vy and ty then act on nothing). Isometric states are
    unchanged: at V = 0 the target is 1 whatever cy."""
    fibre = dataclasses.replace(params.fibre, cy=np.zeros_like(params.fibre.cy))
    return dataclasses.replace(params, fibre=fibre)


def _velocity_sweep(bank: MuscleBank, drives, velocities):
    """Force (F0) and total energy rate (W) at each drive and fascicle velocity, sampled as the
    fascicle passes L0 (:func:`_isovelocity`)."""
    force = np.zeros((len(drives), len(velocities)))
    energy = np.zeros_like(force)
    for i, u in enumerate(drives):
        for j, v in enumerate(velocities):
            out = _isovelocity(bank, [u], v, settle_s=0.12)
            force[i, j] = out.force[0] / bank.f0[0]
            energy[i, j] = out.energy_rate.total[0]
    return force, energy


def check_fig4_biceps_velocity_sweep(params=None) -> CheckResult:
    params = params or load_model_params()
    result = CheckResult("3", "Fig. 4: biceps long-head analogue (40 % slow), velocity sweep",
                         "force and energy move in opposite directions around zero velocity; "
                         "maximal force (~140 % of the maximal isometric force) when stretched "
                         "faster than 1 L0/s, where energy is low; maximal energy near Vmax where "
                         "force is zero; energy per unit isometric force ~0.1 W/N at 40 % drive "
                         "to ~0.2 W/N at 100 %")
    bank = MuscleBank.from_config(["biceps_long_head"], params=params)
    drives = np.array([0.2, 0.4, 0.6, 0.8, 1.0])
    velocities = np.concatenate([np.linspace(-8.5, -1.0, 9), np.linspace(-0.5, 2.0, 6)])
    force, energy = _velocity_sweep(bank, drives, velocities)
    iso = [isometric_at(bank, [u]) for u in drives]
    iso_force_f0 = np.array([o.force[0] / bank.f0[0] for o in iso])
    w_per_n = np.array([o.energy_rate.total[0] / o.force[0] for o in iso])
    full = -1
    stretch = velocities > 1.0
    # the same sweep at U = 1 with the yield effect disabled (without_yield: cy = 0)
    no_yield = MuscleBank.from_config(["biceps_long_head"], params=without_yield(params))
    force_no_yield = _velocity_sweep(no_yield, [1.0], velocities)[0][0]
    iso_no_yield_f0 = isometric_at(no_yield, [1.0]).force[0] / no_yield.f0[0]
    peak_over_iso = {"yield on": float(force[full, stretch].max() / iso_force_f0[full]),
                     "yield off": float(force_no_yield[stretch].max() / iso_no_yield_f0)}
    result.criteria += [
        # "About 140 % of the maximal isometric force", i.e. of the U = 1 isometric force at L0,
        # read from a figure of a model whose analogue parameters were in its lost table: 1.4 +-
        # 0.2. Wide enough for reading a figure and for the yield transient at the sampled
        # instant (0.12 s into the stretch, ty = 0.2 s); narrow enough to reject a lengthening FV
        # that stays near isometric (< 1.2) or rises past VM's (1.38-1.42 per type at the
        # 1.7 L0/s the fascicle reaches; > 1.6 needs a different FV).
        Criterion("U=1 max force stretched > 1 L0/s / U=1 isometric force, yield on",
                  peak_over_iso["yield on"], 1.2, 1.6),
        # Reported, not held: what the slow fibres' yield costs at that stretch (the paper's
        # model, VM 4.0, has yield, so only the yield-on value is its claim).
        Criterion("the same, yield off (cy = 0; reported)", peak_over_iso["yield off"],
                  None, None),
        # Reported, not held: the same peak in F0 (the isometric force at U = 1 is below F0:
        # W and Af are below 1 at the top firing rate).
        Criterion("U=1 max force stretched > 1 L0/s (F0; reported)",
                  float(force[full, stretch].max()), None, None),
        Criterion("energy at that stretch / isometric energy (U=1)",
                  float(energy[full, stretch][np.argmax(force[full, stretch])]
                        / iso[full].energy_rate.total[0]), None, 0.5),
        Criterion("velocity of max energy / Vmax_fast (U=1)",
                  float(velocities[np.argmax(energy[full])] / params.fibre.vmax[FAST]), 0.6, 1.0),
        Criterion("force at the velocity of max energy (F0, U=1)",
                  float(force[full, np.argmax(energy[full])]), None, 0.1),
        Criterion("energy per isometric force at 40 % drive (W/N; paper ~0.1)",
                  float(w_per_n[1]), 0.04, 0.2),
        Criterion("energy per isometric force at 100 % drive (W/N; paper ~0.2)",
                  float(w_per_n[-1]), 0.1, 0.4),
        Criterion("ratio of the two (paper ~2)", float(w_per_n[-1] / w_per_n[1]), 1.5, 3.5),
    ]
    result.data = {"drive": drives, "velocity": velocities, "force_f0": force, "energy_w": energy,
                   "isometric_force_f0": iso_force_f0, "force_f0_no_yield": force_no_yield,
                   "isometric_force_f0_no_yield": iso_no_yield_f0,
                   "peak_over_isometric": peak_over_iso,
                   "w_per_n": w_per_n, "l0_m": bank.l0_m[0], "f0_n": bank.f0[0]}
    return result


# --- items 4-6: Figs. 9-10, cost ----------------------------------------------------------------


def check_fig9_lumped_steady(params=None) -> CheckResult:
    params = params or load_model_params()
    comparison = compare_steady(params, ur=0.8, units_per_type=50)
    result = CheckResult("4", "Fig. 9: steady isometric force, lumped vs natural units",
                         "nearly identical (target: max error within 2 % of F(U=1), "
                         "Fpcsa_S 0.2-0.8)")
    for fs, err in zip(comparison.fpcsa_slow, comparison.max_error_percent, strict=True):
        result.criteria.append(Criterion(f"max |error| % F(U=1), slow {fs:.0%}", float(err),
                                         None, 2.0))
    result.data = {"comparison": comparison}
    return result


FIG10_LIMITS = {"transient_rms_error": 3.0, "mean_error": 3.0, "range_error": 6.0}


def _worst_errors(table) -> dict:
    columns = list(table.columns)
    return {name: float(np.abs(table.rows[:, columns.index(name)]).max()) for name in FIG10_LIMITS}


def check_fig10_lumped_sinusoidal(params=None, progress=None) -> CheckResult:
    params = params or load_model_params()
    muscle = resolve_muscles(["vastus_lateralis"], None, None, 0.8)[0]
    table = compare_sinusoidal(params, muscle, cycles=3, progress=progress)
    law = params.lumped.drive_law
    result = CheckResult("5", f"Fig. 10: sinusoidal drive, lumped ({law}) vs natural units",
                         "lumped close to natural in the transient and the steady state (mean "
                         "force and modulation range); thresholds held: transient RMS < 3 %, "
                         "mean < 3 %, range < 6 % of F(U=1), and no worse than the paper's "
                         "drive-filter law")
    worst = _worst_errors(table)
    for name, limit in FIG10_LIMITS.items():
        result.criteria.append(Criterion(f"worst |{name}| % F(U=1)", worst[name], None, limit))
    data = {"table": table}
    if law != "tsianos2012":
        # a drive-filter law other than the paper's must not follow natural units less well
        # than the paper's does, on the paper's own sinusoids (same W, same cases)
        paper = compare_sinusoidal(with_drive_law(params, "tsianos2012"), muscle, cycles=3)
        paper_worst = _worst_errors(paper)
        for name in FIG10_LIMITS:
            result.criteria.append(Criterion(
                f"worst |{name}| / the same with the tsianos2012 law ({paper_worst[name]:.2f})",
                worst[name] / paper_worst[name], None, 1.0))
        data["paper_law_table"] = paper
    result.data = data
    return result


def check_lumped_cost(params=None, sizes=(1, 100, 1000)) -> CheckResult:
    """Median step time of lumped and natural (20 units per type) banks of 1-1000 muscles."""
    params = params or load_model_params()
    result = CheckResult("6", "Lumped vs natural units: cost",
                         "the lumped model is much cheaper than natural units")
    seconds = {}
    base = resolve_muscles(["vastus_lateralis"], None, None, params.generic.ur_default)[0]
    for n in sizes:
        for scheme in ("lumped", "natural"):
            specs = [dataclasses.replace(base, name=f"m{i}") for i in range(n)]
            natural = dataclasses.replace(params, natural=dataclasses.replace(
                params.natural, units_per_type=20))
            bank = MuscleBank(specs, natural, scheme)
            lp = _path_for(bank)
            drive = np.full(n, 0.5)
            bank.reset(lp)
            steps = max(5, 200 // max(1, n // 20))
            samples = []
            for _ in range(5):
                start = time.perf_counter()
                for _ in range(steps):
                    bank.step(DT, drive, lp)
                samples.append((time.perf_counter() - start) / steps)
            seconds[(scheme, n)] = float(np.median(samples))
    for n in sizes:
        result.criteria.append(Criterion(
            f"natural (20 units/type) / lumped step time, {n} muscles",
            seconds[("natural", n)] / seconds[("lumped", n)], 1.5 if n == max(sizes) else None,
            None))
    # timings depend on what else runs: the figure says under which load they were taken
    result.data = {"seconds_per_step": seconds, "sizes": sizes,
                   "load_average": os.getloadavg()[0], "cpus": os.cpu_count()}
    return result


# --- items 7-8: Figs. 5-6, temperature --------------------------------------------------------
#
# The model quantity compared with the measured heat is the INITIAL energy rate E_a + E_xb: the
# paper says the measured values of the longer contractions "include some recovery energy", which
# "would also overestimate initial energy consumption". The total (with static recovery) is
# reported beside it. Temperature rates are given in mK/s, as the figures show them.


def temperature_rate_k_per_s(energy_rate_w, mass_kg, heat_capacity):
    """dT/dt (K/s) = energy rate (W) / (wet mass (kg) x specific heat (J/(kg K)))."""
    return energy_rate_w / (mass_kg * heat_capacity)


FIG5_MUSCLES = ("soleus", "tibialis_anterior", "biceps_femoris_long_head", "gluteus_maximus",
                "vastus_lateralis", "gastrocnemius_medialis", "triceps_long_head",
                "biceps_long_head", "rectus_femoris")
MVC_DRIVES = (1.0, 0.8)  # subjects reaching true maximal drive, and undershooting it


def check_fig5_fibre_composition(params=None) -> CheckResult:
    params = params or load_model_params()
    result = CheckResult("7", "Fig. 5: temperature rate at MVC vs % fast fibres",
                         "strong positive correlation between the temperature rate at MVC "
                         "(isometric, L0; model: initial energy) and the percentage of fast "
                         "fibres, for subjects reaching U = 1 and undershooting (U = 0.8)")
    bank = MuscleBank.from_config(list(FIG5_MUSCLES), params=params)
    c = params.energetics.heat_capacity
    fast = 100 * bank.fpcsa[:, FAST]
    rates = {"initial": {}, "total": {}}  # mK/s per muscle, by MVC drive
    for u in MVC_DRIVES:
        out = isometric_at(bank, np.full(bank.n, u))
        rates["initial"][u] = 1e3 * temperature_rate_k_per_s(_initial_w(out), bank.mass_kg, c)
        rates["total"][u] = 1e3 * temperature_rate_k_per_s(out.energy_rate.total, bank.mass_kg, c)
        # "Strong positive correlation": r >= 0.8, on the initial energy (the paper's comparison).
        result.criteria.append(Criterion(
            f"U = {u} at MVC: Pearson r, initial rate vs % fast",
            float(np.corrcoef(fast, rates["initial"][u])[0, 1]), 0.8, None))
        # The same with recovery, and the absolute rates: reported, not held (the paper's
        # measured values were not recoverable).
        result.criteria.append(Criterion(
            f"U = {u} at MVC: Pearson r, total rate vs % fast (reported)",
            float(np.corrcoef(fast, rates["total"][u])[0, 1]), None, None))
        for kind in ("initial", "total"):
            for pick, which in ((np.argmin, "lowest"), (np.argmax, "highest")):
                i = int(pick(rates[kind][u]))
                result.criteria.append(Criterion(
                    f"U = {u} at MVC: {kind} dT/dt, {which}: {bank.names[i]} (mK/s)",
                    float(rates[kind][u][i]), None, None))
    result.data = {"names": bank.names, "fast_percent": fast, "mass_kg": bank.mass_kg,
                   "rates_mk_per_s": rates}
    return result


def check_fig6_drive(params=None) -> CheckResult:
    params = params or load_model_params()
    result = CheckResult("8", "Fig. 6: vastus lateralis, temperature rate vs force",
                         "temperature rate (model: initial energy) rises with force over 10-90 % "
                         "MVC, more steeply at high force as fast fibres are recruited (the paper "
                         "notes the model underestimates the data at low force)")
    bank = MuscleBank.from_config(["vastus_lateralis"], params=params)
    c = params.energetics.heat_capacity
    mass = bank.mass_kg[0]
    series = {}
    levels = np.linspace(0.1, 0.9, 9)
    for mvc_drive in MVC_DRIVES:
        outs = [isometric_at(bank, [mvc_drive * p]) for p in levels]
        mvc = isometric_at(bank, [mvc_drive])
        s = {"levels": levels,
             "force_pct": np.array([100 * o.force[0] / mvc.force[0] for o in outs])}
        for kind, rate_w in (("initial", _initial_w), ("total", lambda o: o.energy_rate.total)):
            s[kind] = np.array([1e3 * temperature_rate_k_per_s(rate_w(o)[0], mass, c)
                                for o in outs])
            s[f"{kind}_at_mvc"] = float(1e3 * temperature_rate_k_per_s(rate_w(mvc)[0], mass, c))
        series[mvc_drive] = s
        # the shape, on the initial energy: a rise at every step, and steeper at high force
        slope = np.gradient(s["initial"], s["force_pct"])
        result.criteria += [
            Criterion(f"MVC at U = {mvc_drive}: min rise of initial rate between levels (mK/s)",
                      float(np.diff(s["initial"]).min()), 0.0, None),
            Criterion(f"MVC at U = {mvc_drive}: initial, slope at 90 % / slope at 20 % force",
                      float(slope[-1] / slope[1]), 1.0, None)]
        # the total beside it and the absolute rates at MVC: reported, not held
        slope_total = np.gradient(s["total"], s["force_pct"])
        result.criteria += [
            Criterion(f"MVC at U = {mvc_drive}: total, slope 90 % / 20 % force (reported)",
                      float(slope_total[-1] / slope_total[1]), None, None),
            Criterion(f"MVC at U = {mvc_drive}: initial dT/dt at 100 % MVC (mK/s)",
                      s["initial_at_mvc"], None, None),
            Criterion(f"MVC at U = {mvc_drive}: total dT/dt at 100 % MVC (mK/s)",
                      s["total_at_mvc"], None, None)]
    result.data = {"series": series, "mass_kg": mass}
    return result
