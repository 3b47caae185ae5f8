"""Validation against Tsianos, Rustin & Loeb 2012: the paper's figures as checks.

A check computes what the model gives for one of the paper's claims, compares it with explicit
criteria (numbers, signs, orderings, ratios) and returns a :class:`CheckResult`; ``plot`` draws
the figure. ``vm-ros validate`` runs them all, writes one PNG per figure and a CSV of the numbers.
The tests in test/test_validation.py assert the same criteria.

Energy is converted to muscle temperature rate with the heat capacity 3.75 kJ/(kg K):
dT/dt = total rate / (wet mass * c).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from vm_ros.model import MuscleBank, load_model_params
from vm_ros.model.curves import force_length_cheng2000, tendon_length_at_force
from vm_ros.model.lumped_fit import compare_sinusoidal, compare_steady
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
            fl = np.exp(-np.abs((out.length_l0[0] ** params.fibre.beta[t] - 1)
                                / params.fibre.omega[t]) ** params.fibre.rho[t])
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


def check_fig3_fibre_type_energy(params=None) -> CheckResult:
    params = params or load_model_params()
    result = CheckResult("2", "Fig. 3: energy vs drive, velocity and length, slow vs fast",
                         "fast fibres can consume more than five times as much energy per unit "
                         "time as slow fibres for the same force; energy rises with drive and "
                         "shortening speed, falls on both sides of L0 asymmetrically; E_a constant "
                         "across V and L")
    per_newton, curves = {}, {}
    for t, name, bank in _pure_fibre_banks(params):
        drives = np.linspace(0.1, 1.0, 10)
        by_drive = [isometric_at(bank, [u]) for u in drives]
        initial = np.array([o.energy_rate.activation[0] + o.energy_rate.cross_bridge[0]
                            for o in by_drive])
        force = np.array([o.force[0] for o in by_drive])
        per_newton[name] = initial / force
        lengths = np.round(np.linspace(0.6, 1.4, 9), 3)
        by_length = [isometric_at(bank, [1.0], l=l) for l in lengths]
        velocities = np.array([-4.0, -2.0, -1.0, -0.5, 0.0])
        by_velocity = [_isovelocity(bank, [1.0], v) for v in velocities]
        curves[name] = {
            "drive": drives, "e_a_drive": [o.energy_rate.activation[0] for o in by_drive],
            "e_xb_drive": [o.energy_rate.cross_bridge[0] for o in by_drive],
            "length": lengths, "total_length": [o.energy_rate.total[0] for o in by_length],
            "e_a_length": [o.energy_rate.activation[0] for o in by_length],
            "e_xb_length": [o.energy_rate.cross_bridge[0] for o in by_length],
            "fl_length": force_length_cheng2000(lengths, params.fibre.omega[t],
                                                params.fibre.beta[t], params.fibre.rho[t]),
            "velocity": velocities, "total_velocity": [o.energy_rate.total[0] for o in by_velocity],
            "e_a_velocity": [o.energy_rate.activation[0] for o in by_velocity],
            "mass_kg": bank.mass_kg[0]}
    ratio = per_newton["fast"] / per_newton["slow"]
    result.criteria.append(Criterion("fast/slow initial energy per newton, isometric (min over "
                                     "drive 0.1-1)", float(ratio.min()), 5.0, None))
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
    result.data = {"per_newton": per_newton, "curves": curves}
    return result


# --- item 3: Fig. 4 ---------------------------------------------------------------------------


def check_fig4_biceps_velocity_sweep(params=None) -> CheckResult:
    params = params or load_model_params()
    result = CheckResult("3", "Fig. 4: biceps long-head analogue (40 % slow), velocity sweep",
                         "force and energy move in opposite directions around zero velocity; "
                         "maximal force (~140 % F0) when stretched faster than 1 L0/s, where "
                         "energy is low; maximal energy near Vmax where force is zero; energy per "
                         "unit isometric force ~0.1 W/N at 40 % drive to ~0.2 W/N at 100 %")
    bank = MuscleBank.from_config(["biceps_long_head"], params=params)
    drives = np.array([0.2, 0.4, 0.6, 0.8, 1.0])
    velocities = np.concatenate([np.linspace(-8.5, -1.0, 9), np.linspace(-0.5, 2.0, 6)])
    force = np.zeros((len(drives), len(velocities)))
    energy = np.zeros_like(force)
    for i, u in enumerate(drives):
        for j, v in enumerate(velocities):
            out = _isovelocity(bank, [u], v, settle_s=0.12)
            force[i, j] = out.force[0] / bank.f0[0]
            energy[i, j] = out.energy_rate.total[0]
    iso = [isometric_at(bank, [u]) for u in drives]
    w_per_n = np.array([o.energy_rate.total[0] / o.force[0] for o in iso])
    full = -1
    stretch = velocities > 1.0
    result.criteria += [
        Criterion("max force at U=1 when stretched > 1 L0/s (F0)",
                  float(force[full, stretch].max()), 1.2, 1.8),
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


def check_fig10_lumped_sinusoidal(params=None, progress=None) -> CheckResult:
    params = params or load_model_params()
    muscle = resolve_muscles(["vastus_lateralis"], None, None, 0.8)[0]
    table = compare_sinusoidal(params, muscle, cycles=3, progress=progress)
    result = CheckResult("5", "Fig. 10: sinusoidal drive, lumped vs natural units",
                         "lumped close to natural in the transient and the steady state (mean "
                         "force and modulation range); thresholds held: transient RMS < 3 %, "
                         "mean < 3 %, range < 6 % of F(U=1)")
    columns = list(table.columns)
    for name, limit in FIG10_LIMITS.items():
        worst = float(np.abs(table.rows[:, columns.index(name)]).max())
        result.criteria.append(Criterion(f"worst |{name}| % F(U=1)", worst, None, limit))
    result.data = {"table": table}
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
    result.data = {"seconds_per_step": seconds, "sizes": sizes}
    return result


# --- items 7-8: Figs. 5-6, temperature --------------------------------------------------------


def temperature_rate_k_per_s(total_w, mass_kg, heat_capacity):
    return total_w / (mass_kg * heat_capacity)


FIG5_MUSCLES = ("soleus", "tibialis_anterior", "biceps_femoris_long_head", "gluteus_maximus",
                "vastus_lateralis", "gastrocnemius_medialis", "triceps_long_head",
                "biceps_long_head", "rectus_femoris")


def check_fig5_fibre_composition(params=None) -> CheckResult:
    params = params or load_model_params()
    result = CheckResult("7", "Fig. 5: temperature rate at MVC vs % fast fibres",
                         "strong positive correlation between the temperature rate at MVC "
                         "(isometric, L0) and the percentage of fast fibres, for subjects "
                         "reaching U = 1 and undershooting (U = 0.8)")
    bank = MuscleBank.from_config(list(FIG5_MUSCLES), params=params)
    c = params.energetics.heat_capacity
    fast = 100 * bank.fpcsa[:, FAST]
    rates = {}
    for u in (1.0, 0.8):
        out = isometric_at(bank, np.full(bank.n, u))
        rates[u] = temperature_rate_k_per_s(out.energy_rate.total, bank.mass_kg, c)
        r = float(np.corrcoef(fast, rates[u])[0, 1])
        result.criteria.append(Criterion(f"Pearson r, U = {u} at MVC", r, 0.8, None))
    result.data = {"names": bank.names, "fast_percent": fast, "rates_k_per_s": rates}
    return result


def check_fig6_drive(params=None) -> CheckResult:
    params = params or load_model_params()
    result = CheckResult("8", "Fig. 6: vastus lateralis, temperature rate vs force",
                         "temperature rate rises with force over 10-90 % MVC, more steeply at high "
                         "force as fast fibres are recruited (the paper notes the model "
                         "underestimates the data at low force)")
    bank = MuscleBank.from_config(["vastus_lateralis"], params=params)
    c = params.energetics.heat_capacity
    series = {}
    for mvc_drive in (1.0, 0.8):
        levels = np.linspace(0.1, 0.9, 9)
        outs = [isometric_at(bank, [mvc_drive * p]) for p in levels]
        f_mvc = isometric_at(bank, [mvc_drive]).force[0]
        force_pct = np.array([100 * o.force[0] / f_mvc for o in outs])
        rate = np.array([temperature_rate_k_per_s(o.energy_rate.total[0], bank.mass_kg[0], c)
                         for o in outs])
        series[mvc_drive] = (levels, force_pct, rate)
        result.criteria.append(Criterion(f"MVC at U = {mvc_drive}: min rise of rate between "
                                         "levels (K/s)", float(np.diff(rate).min()), 0.0, None))
        slope = np.gradient(rate, force_pct)
        result.criteria.append(Criterion(f"MVC at U = {mvc_drive}: slope at 90 % / slope at "
                                         "20 % force", float(slope[-1] / slope[1]), 1.0, None))
    result.data = {"series": series}
    return result
