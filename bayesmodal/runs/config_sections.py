"""The sections of a run configuration, each checked on its own (``parse_config`` calls
them in the order of the TOML document's sections).

Each ``_parse_<section>(..., kw, err)`` reads the values ``parse_config`` has type-checked
(``values``: ``(section, key) -> value``), puts what ``RunConfig`` takes into ``kw`` and
reports every problem through ``err(key, message)``, so that one ``ConfigError`` lists
them all.  Nothing here is public; ``bayesmodal.runs.config`` is the interface.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from .._errors import ConfigError, ModelError
from ..data import in_data_root
from ..inference.moves import move_spec
from ..inference.noise_spec import accepted_noise, parse_noise
from ..inference.record_scale import NOISE_SCALES
from ..inference.spec import INIT_METHODS, INITIAL_STATES
from ..inference.threads import resolve_threads
from ..model.effects import EXTENSIONS
from ..model.rigs import PRESETS, load_rig, rig_from_dict, rig_to_dict
from ..model.system import DAMPING_MODELS, ECP210_SPRINGS_N_M, LinearModel, Rig
from ..reading import REST_OFFSETS, TIME_BASES, ReadOptions, parse_scale
from .identify_spec import identify_problems

#: Burn-in steps of a run whose ``[sampler]`` does not give them (``RunConfig.burn``).
DEFAULT_BURN = 1000


@dataclass(frozen=True)
class PriorOverride:
    """Uniform prior bounds for one parameter; ``scale="log"`` for log-uniform."""

    lo: float
    hi: float
    scale: str = "linear"


def _resolve_data(path_text: str, base: Path) -> Path | None:
    p = Path(path_text).expanduser()
    candidates = [p] if p.is_absolute() else [base / p]
    candidates += in_data_root(p)
    for c in candidates:
        if c.is_file():
            return c.resolve()
    return None


def _resolve_files(files, key: str, err, base: Path, check_files: bool) -> tuple[str, ...]:
    """Each path resolved (``_resolve_data``); a missing file is reported under ``key``."""
    out = []
    for f in files:
        p = _resolve_data(f, base)
        if p is None and check_files:
            err(key, f"file not found: {f!r} (looked relative to {base} and in the data root "
                "$BAYESMODAL_DATA or ../shared/data)")
        out.append(str(p) if p is not None else f)
    return tuple(out)


def _parse_data(values, kw, err, base: Path, check_files: bool):
    """``[data]``: the files, the reading options; returns the files and m per count."""
    files = values.get(("data", "files"))
    if files is None:
        err("data.files", "missing: list the data files to fit")
        files = []
    elif not files or not all(isinstance(f, str) for f in files):
        err("data.files", f"must be a non-empty list of paths, got {files!r}")
        files = []
    kw["data_files"] = _resolve_files([f for f in files if isinstance(f, str)], "data.files",
                                      err, base, check_files)

    heldout = values.get(("data", "heldout"))
    if heldout is not None:
        if not all(isinstance(f, str) for f in heldout):
            err("data.heldout", f"must be a list of paths, got {heldout!r}")
        else:
            kw["heldout_files"] = _resolve_files(heldout, "data.heldout", err, base,
                                                 check_files)

    mpc = values.get(("data", "m_per_count"))
    if mpc is not None:
        if not (0 < abs(mpc) < 1):  # negative: encoders counting the other way
            err("data.m_per_count", f"must be non-zero and within (-1, 1) m per count "
                f"(negative for encoders counting the other way), got {mpc!r}")
        kw["m_per_count"] = float(mpc)

    cols = values.get(("data", "columns"))
    if cols is not None:
        bad = [k for k, c in cols.items()
               if isinstance(c, bool) or not isinstance(c, (str, int))]
        if bad:
            err(f"data.columns.{bad[0]}", "must be a column name or a 1-based column number, "
                f"got {cols[bad[0]]!r}")
        else:
            try:
                opts = ReadOptions(columns={k: str(c) for k, c in cols.items()})
                kw["columns"] = opts.column_map
            except ConfigError as exc:
                err("data.columns", str(exc))
    for key in ("input_scale", "time_scale"):
        val = values.get(("data", key))
        if val is None:
            continue

        try:
            # the input may be reversed (a negative input_scale); time runs forwards
            kw[key] = parse_scale(str(val), key, signed=key == "input_scale")
        except ConfigError as exc:
            err(f"data.{key}", str(exc))

    time_base = values.get(("data", "time_base"))
    if time_base is not None:
        if time_base not in TIME_BASES:
            err("data.time_base",
                f"must be one of {', '.join(TIME_BASES)}, got {time_base!r}")
        else:
            kw["time_base"] = time_base

    rest_offset = values.get(("data", "rest_offset"))
    if rest_offset is not None:
        if rest_offset not in REST_OFFSETS:
            err("data.rest_offset", f"must be one of {', '.join(REST_OFFSETS)} (subtract "
                "each output's rest level before the first input, or its final rest), got "
                f"{rest_offset!r}")
        else:
            kw["rest_offset"] = rest_offset
    release = values.get(("data", "release"))
    if release == "auto":
        # the cut decay starts displaced, and a run starts every record from rest
        err("data.release", "a hand-released decay needs its initial state estimated, and a "
            "run starts every record from rest; fit it with `bayesmodal lsq` or `bayesmodal "
            "sample` and --release auto --initial-state estimate")
    elif release is not None and release != "none":
        err("data.release", f"must be 'none' in a run (a hand release is fitted with "
            f"`bayesmodal lsq --release auto`), got {release!r}")

    window = {k: values[("data", k)] for k in ("t_start", "t_end") if ("data", k) in values}
    if window:
        try:
            ReadOptions(**window)
            kw.update(window)
        except ConfigError as exc:
            err("data." + next(iter(window)), str(exc))
    return files, mpc


def _parse_model(raw, values, kw, err, base: Path, mpc) -> None:
    """``[rig]`` and ``[model]``: springs or a rig description, damping, extensions."""
    springs = values.get(("rig", "springs_n_m"))
    if springs is not None:
        if not springs or not all(isinstance(k, (int, float)) and not isinstance(k, bool)
                                  and k > 0 for k in springs):
            err("rig.springs_n_m", f"must be a non-empty list of positive N/m, got {springs!r}")
        else:
            kw["springs_n_m"] = tuple(float(k) for k in springs)
    _parse_rig(raw.get("rig"), values, kw, base, err)
    if mpc is None and kw.get("rig") is not None:
        # encoder files take the scale of the rig's count sensors, as on the command line
        scales = {float(s["m_per_unit"]) for s in kw["rig"].get("sensors", [])
                  if s.get("unit") == "count" and s.get("m_per_unit") is not None}
        if len(scales) == 1:
            kw["m_per_count"] = scales.pop()

    # a rig description may declare its damping ([dampers] proportional = true/false)
    prop = ((kw.get("rig") or {}).get("dampers") or {}).get("proportional")
    declared = None if prop is None else ("proportional" if prop else "free")
    given = values.get(("model", "damping"))
    damping = given if given is not None else (declared or "free")
    if damping not in DAMPING_MODELS:
        err("model.damping", f"must be one of {DAMPING_MODELS}, got {damping!r}")
    elif given is not None and declared is not None and given != declared:
        err("model.damping", f"{given!r} contradicts the rig's [dampers] proportional = "
            f"{str(prop).lower()}; drop one of the two")
    kw["damping"] = damping
    exts = values.get(("model", "extensions"), [])
    try:
        known = tuple(EXTENSIONS)
    except ImportError:
        known = ()
    for e in exts:
        if e not in known:
            err("model.extensions", f"unknown extension {e!r}; known: {list(known)}")
    kw["extensions"] = tuple(str(e) for e in exts)


def _parse_likelihood(raw, values, kw, err, files) -> None:
    """``[likelihood]``, ``[records]``, ``[crossval]`` and ``[identify]``."""
    temp = values.get(("likelihood", "temperature"))
    if isinstance(temp, str):
        if temp != "loro":
            err("likelihood.temperature", "must be a number > 0 or \"loro\" (calibrated "
                f"by leave-one-record-out coverage), got {temp!r}")
        else:
            kw["temperature"] = temp
    elif temp is not None:
        if not temp > 0:
            err("likelihood.temperature", f"must be > 0, got {temp!r}")
        kw["temperature"] = float(temp)
    state = values.get(("likelihood", "initial_state"))
    if state is not None:
        if state not in INITIAL_STATES:
            err("likelihood.initial_state", f"must be one of {INITIAL_STATES}, got {state!r}")
        kw["initial_state"] = state
    per = values.get(("records", "per_record"))
    if per is not None:
        for pname, kind in per.items():
            if kind not in ("independent", "hierarchical", "shared"):
                err(f"records.per_record.{pname}", "must be 'independent', 'hierarchical' or "
                    "'shared', "
                    f"got {kind!r}")
        kw["per_record"] = {str(k): str(v) for k, v in per.items()}
    if ("records", "noise_per_record") in values:
        kw["noise_per_record"] = values[("records", "noise_per_record")]
    if ("records", "noise_scale") in values:
        v = values[("records", "noise_scale")]
        if v not in NOISE_SCALES:
            err("records.noise_scale", f"must be 'none', 'response' or 'power', got {v!r}")
        kw["noise_scale"] = v
    if ("crossval", "enabled") in values:
        kw["crossval"] = values[("crossval", "enabled")]
    for key, lo in (("draws", 2), ("walkers", 4), ("steps", 10)):
        v = values.get(("crossval", key))
        if v is not None:
            if v < lo:
                err(f"crossval.{key}", f"must be >= {lo}, got {v}")
            kw[f"crossval_{key}"] = v
    if kw.get("crossval") and len(files) < 2:
        err("crossval.enabled", "leave-one-record-out needs at least two [data.files]")
    _parse_identify(raw.get("identify"), err, kw)

    noise = values.get(("likelihood", "noise"), "ar1")

    try:
        parse_noise(noise)
    except ConfigError:
        err("likelihood.noise", f"must be one of {accepted_noise()}, got {noise!r}")
    kw["noise"] = noise


def _parse_sampler(values, kw, err) -> None:
    """``[sampler]``: walkers, steps, burn-in, thinning, restart or pruning, moves."""
    for key, lo in (("walkers", 4), ("steps", 1), ("burn", 0), ("thin", 1), ("seed", 0)):
        v = values.get(("sampler", key))
        if v is not None:
            if v < lo:
                err(f"sampler.{key}", f"must be >= {lo}, got {v}")
            kw[key] = v
    if values.get(("sampler", "burn"), 0) >= values.get(("sampler", "steps"), 5000):
        err("sampler.burn", "must be smaller than sampler.steps")
    burn = values.get(("sampler", "burn"), DEFAULT_BURN)
    for key in ("restart", "prune"):  # steps of the burn-in, one or the other
        step = values.get(("sampler", key))
        if step is None:
            continue
        if key == "prune" and "restart" in kw:
            err("sampler.prune", "give restart or prune, not both: restart re-centres "
                "every walker, prune moves only the stranded ones")
        elif not 1 <= step < burn:
            err(f"sampler.{key}", f"must be in [1, sampler.burn) = [1, {burn}) so that "
                f"every retained draw comes after it, got {step}")
        kw[key] = step
        cv_steps = values.get(("crossval", "steps"))
        if cv_steps is not None and step >= cv_steps // 2:  # the folds burn half their steps
            err("crossval.steps", f"the folds burn in {cv_steps // 2} steps (half of "
                f"crossval.steps), not more than sampler.{key} = {step}; give at least "
                f"{2 * step + 2} steps")
    init = values.get(("sampler", "init"))
    if init is not None:
        if init not in INIT_METHODS:
            err("sampler.init", f"must be 'ball' or 'laplace', got {init!r}")
        kw["init"] = init
    threads = values.get(("sampler", "threads"))
    if threads is not None:
        try:
            kw["threads"] = resolve_threads(threads)
        except ConfigError as exc:
            err("sampler.threads", str(exc))
    moves = values.get(("sampler", "moves"))
    if moves is not None:
        for problem in move_spec(moves)[1]:
            err("sampler.moves", problem)
        kw["moves"] = moves


def _parse_outputs(values, kw, err) -> None:
    """``[outputs]`` and ``[evidence]``."""
    out = values.get(("outputs", "dir"))
    if out is not None:
        pp = PurePosixPath(out.replace("\\", "/"))
        if pp.is_absolute() or Path(out).is_absolute() or ".." in pp.parts or not out.strip():
            err("outputs.dir", f"must be a relative folder inside the output root, got {out!r}")
        kw["out_dir"] = out
    for key in ("plots", "report", "ema", "pointwise_loglik"):
        if ("outputs", key) in values:
            kw[key] = values[("outputs", key)]
    chain = values.get(("outputs", "chain"))
    if chain is not None:
        if chain not in ("compact", "full"):
            err("outputs.chain", f"must be 'compact' or 'full', got {chain!r}")
        kw["chain_storage"] = chain
    ck = values.get(("outputs", "checkpoint_every_s"))
    if ck is not None:
        if not ck > 0:
            err("outputs.checkpoint_every_s", f"must be > 0 seconds, got {ck!r}")
        kw["checkpoint_every_s"] = float(ck)
    if ("evidence", "enabled") in values:
        kw["evidence"] = values[("evidence", "enabled")]
    nlive = values.get(("evidence", "nlive"))
    if nlive is not None:
        if nlive < 10:
            err("evidence.nlive", f"must be >= 10 live points, got {nlive}")
        kw["evidence_nlive"] = nlive
    dlogz = values.get(("evidence", "dlogz"))
    if dlogz is not None:
        if not dlogz > 0:
            err("evidence.dlogz", f"must be > 0, got {dlogz!r}")
        kw["evidence_dlogz"] = float(dlogz)
    pd = values.get(("outputs", "predictive_draws"))
    if pd is not None:
        if pd < 0:
            err("outputs.predictive_draws", f"must be >= 0, got {pd}")
        kw["predictive_draws"] = pd


def _parse_priors(raw, kw, err) -> None:
    """``[priors]``: bounds and scale of named parameters."""
    priors: dict[str, PriorOverride] = {}
    ptable = raw.get("priors", {})
    if isinstance(ptable, dict):
        for pname, spec in ptable.items():
            key = f"priors.{pname}"
            lo = hi = None
            scale = "linear"
            if isinstance(spec, list) and len(spec) == 2:
                lo, hi = spec
            elif isinstance(spec, dict):
                extra = set(spec) - {"lo", "hi", "scale"}
                if extra:
                    err(key, f"unknown field(s) {sorted(extra)}; use lo, hi, scale")
                lo, hi, scale = spec.get("lo"), spec.get("hi"), spec.get("scale", "linear")
            else:
                err(key, f"must be [lo, hi] or {{lo, hi, scale}}, got {spec!r}")
                continue
            if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (lo, hi)):
                err(key, f"lo and hi must be numbers, got {lo!r}, {hi!r}")
                continue
            if not lo < hi:
                err(key, f"impossible prior: lo = {lo} is not below hi = {hi}")
            if scale not in ("linear", "log"):
                err(key, f"scale must be 'linear' or 'log', got {scale!r}")
            if scale == "log" and lo <= 0:
                err(key, f"a log-uniform prior needs lo > 0, got {lo}")
            priors[_noise_alias(pname)] = PriorOverride(float(lo), float(hi), str(scale))
        if not kw.get("per_record") and not kw.get("noise_per_record"):
            # several records rename parameters (g_v[rec], mu_g_v): the runner checks them
            _check_prior_names(priors, kw, err)
    kw["priors"] = priors


def _check_prior_names(priors, kw, err) -> None:
    try:
        if kw.get("rig") is not None:
            rig = rig_from_dict(kw["rig"])
        else:
            rig = Rig(kw.get("springs_n_m", ECP210_SPRINGS_N_M))
        model = LinearModel(rig, kw.get("damping", "free"))
    except ValueError:
        return
    n = model.n_outputs
    allowed = set(model.names) | {f"sigma_{i + 1}" for i in range(n)} | {
        f"phi_{i + 1}" for i in range(n)}
    try:
        for e in kw.get("extensions", ()):
            if e in EXTENSIONS:
                allowed |= set(EXTENSIONS[e].names(model.rig))
    except (ImportError, AttributeError):
        pass
    for pname, pr in priors.items():
        if pname not in allowed:
            err(f"priors.{pname}", f"unknown parameter; expected one of {sorted(allowed)}")
        elif (pname.startswith("m") or pname == "g_v") and pr.lo < 0:
            err(f"priors.{pname}", f"impossible prior: {pname} must be positive, lo = {pr.lo}")
        elif pname.startswith("c") and pr.lo < 0:
            err(f"priors.{pname}", f"impossible prior: damping cannot be negative, lo = {pr.lo}")
        elif pname.startswith("sigma_") and pr.lo < 0:
            err(f"priors.{pname}", f"impossible prior: a noise scale cannot be negative, "
                f"lo = {pr.lo}")
        elif pname.startswith("phi_") and not -1 <= pr.lo < pr.hi <= 1:
            err(f"priors.{pname}", f"impossible prior: an AR(1) coefficient lies in [-1, 1], "
                f"got [{pr.lo}, {pr.hi}]")


def _noise_alias(name: str) -> str:
    """``sigma1`` -> ``sigma_1`` and ``phi2`` -> ``phi_2`` (the inference names)."""
    for stem in ("sigma", "phi"):
        rest = name[len(stem):]
        if name.startswith(stem) and rest.isdigit():
            return f"{stem}_{rest}"
    return name


def _parse_identify(table, err, kw) -> None:
    """``[identify]``: the workflow's options (types are checked by ``_SCHEMA``)."""
    if isinstance(table, dict) and "enabled" not in table and table:
        err("identify.enabled", "is missing, so the other [identify] options would be "
            "ignored; set enabled = true to run the workflow (false to keep the table off)")
    if not isinstance(table, dict) or not table.get("enabled", False):
        return
    opts = {k: v for k, v in table.items() if k != "enabled"}
    cands = opts.get("candidates")
    if cands is not None:
        unknown = [c for c in cands if c not in EXTENSIONS]
        if unknown or not cands:
            err("identify.candidates", f"unknown effects {unknown}; known: {list(EXTENSIONS)}"
                if unknown else "must name at least one effect")
        opts["candidates"] = tuple(cands)
    for key, message in identify_problems(opts):
        err(f"identify.{key}", message)
    kw["identify"] = opts


def _parse_rig(table, values, kw, base: Path, err) -> None:
    """``[rig] file = ...`` or an inline description: the canonical description in kw."""
    if not isinstance(table, dict):
        return
    inline = {k: v for k, v in table.items() if k not in ("springs_n_m", "file")}
    given = [k for k in ("springs_n_m", "file") if k in table] + (["inline tables"] if inline
                                                                   else [])
    if len(given) > 1:
        err("rig", f"give one of springs_n_m, file or an inline description, got {given}")
        return
    if not (inline or "file" in table):
        return

    try:
        if inline:
            rig = rig_from_dict(inline, where="inline description")
        else:
            f = values.get(("rig", "file"))
            if f is None:
                return
            p = Path(f).expanduser()
            rig = load_rig(f if f in PRESETS else (p if p.is_absolute() else base / p))
    except ModelError as exc:
        err("rig", str(exc))
        return
    kw["rig"] = rig_to_dict(rig)
    kw["springs_n_m"] = rig.springs_n_m
