"""The benchmark's Hydra sweeper: the basic sweeper's grids, a union of every codec's curve, stable job folders, resume.

Hydra's basic sweeper runs one cartesian grid. A benchmark wants the *union* of one grid per codec (a quantization
step for one, a rank for another), so ``sweep=all`` sets ``hydra.sweeper.union: true`` and this sweeper builds,
for every registered codec, the grid that its own ``configs/sweep/rd_<name>.yaml`` declares (composed through
Hydra, so a codec added later with its two yaml files joins ``sweep=all`` without any change here). The
command-line overrides (``dataset=cmu_test``, or a sweep like ``dataset=cmu_test,synthetic``) apply to every job.

Each job writes into ``<sweep dir>/<codec>/<its varying overrides>`` instead of ``<sweep dir>/<job number>``,
so a sweep that is killed and re-run with the same ``hydra.sweep.dir`` finds the folders of the jobs that
finished (``job.json`` with ``"status": "done"`` and a ``results.jsonl`` whose every line parses) and does not
launch them again; a half-finished job resumes clip by clip (:mod:`mocapbench.experiments.run`).

A job is a shard (:mod:`mocapbench.experiments.shards`): each codec config's clips are cut into the fewest shards
whose estimated CPU time stays under ``shard.max_cpu_s`` (per-frame costs from
:mod:`mocapbench.experiments.cost`), each in ``<config folder>/shard-<i>-of-<n>`` (the config folder itself when
one shard is enough). The number of shards of each config and the packing (``shard.packing``) are kept in
``<sweep dir>/shards.json`` and reused on resume, so a re-run finds the same folders and the same clips in each
whatever the cost file says by then.

Selected with ``override hydra/sweeper: mocapbench`` in ``configs/benchmark.yaml``.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import re
import sys
import time
from collections import OrderedDict
from pathlib import Path
from typing import Any, Sequence

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override
from hydra.plugins.sweeper import Sweeper
from hydra.types import RunMode
from omegaconf import OmegaConf

__all__ = ["RdSweeper", "job_folder", "is_job_done", "longest_first", "JOB_FILE", "SHARDS_FILE"]

log = logging.getLogger(__name__)

JOB_FILE = "job.json"
SHARDS_FILE = "shards.json"
_MAX_SLUG = 100


def job_folder(codec: str, varying: Sequence[str]) -> str:
    """The job's folder below the sweep dir: ``<codec>/<k=v,...>`` of its varying overrides (``default`` if none).

    Characters outside ``[A-Za-z0-9._=,+-]`` become ``_``; a slug longer than 100 characters is shortened and
    suffixed with a hash of the full text, so distinct jobs never share a folder.
    """
    text = ",".join(sorted(varying)) or "default"
    slug = re.sub(r"[^A-Za-z0-9._=,+-]", "_", text)
    if len(slug) > _MAX_SLUG:
        slug = slug[: _MAX_SLUG - 13] + "-" + hashlib.sha1(text.encode()).hexdigest()[:12]
    return f"{re.sub(r'[^A-Za-z0-9._+-]', '_', codec)}/{slug}"


def is_job_done(folder: Path) -> bool:
    """Whether the job folder holds a finished job: ``job.json`` says done and every results line parses."""
    from mocapbench.experiments.results import RESULTS_FILE, is_intact

    try:
        done = json.loads((folder / JOB_FILE).read_text()).get("status") == "done"
    except (OSError, ValueError):
        return False
    if done and not is_intact(folder / RESULTS_FILE):
        log.warning("%s: %s has a line that does not parse: the job runs again", folder, RESULTS_FILE)
        return False
    return done


def longest_first(folders: Sequence[str], estimates: dict[str, float]) -> list[int]:
    """Indices of ``folders`` by estimated CPU seconds, longest first (a folder without an estimate counts 0).

    The launcher hands jobs to the workers in this order, so the workers finish together instead of one running a
    long job alone at the end (the longest-processing-time-first schedule the estimate assumes). Jobs of equal
    estimate keep their order.
    """
    return sorted(range(len(folders)), key=lambda i: -estimates.get(folders[i], 0.0))


def _evenly(items: list[Any], count: int | None) -> list[Any]:
    """At most ``count`` items spread evenly over ``items``, the first and the last included."""
    if count is None or count <= 0 or len(items) <= count:
        return items
    if count == 1:
        return [items[len(items) // 2]]
    picks = sorted({round(i * (len(items) - 1) / (count - 1)) for i in range(count)})
    return [items[i] for i in picks]


def _product(overrides: Sequence[Override]) -> list[list[str]]:
    """Cartesian product of parsed overrides, as the basic sweeper builds it (one ``k=v`` list per job)."""
    lists: OrderedDict[str, list[str]] = OrderedDict()
    for override in overrides:
        key = override.get_key_element()
        if override.is_sweep_override():
            if not override.is_discrete_sweep():
                raise ValueError(f"the mocapbench sweeper supports comma lists only, got {override.input_line!r}")
            lists[key] = [f"{key}={value}" for value in override.sweep_string_iterator()]
        else:
            lists[key] = [f"{key}={override.get_value_element_as_str()}"]
    return [list(point) for point in itertools.product(*lists.values())]


def _saved_plan(plan_path: Path, jobs: list[tuple[str, list[str]]]) -> tuple[str, dict[str, int]]:
    """``(packing, {folder: shard count})`` of ``shards.json``; a new sweep takes the packing its jobs ask for."""
    from mocapbench.experiments import shards

    asked = [o.split("=", 1)[1] for _, overrides in jobs for o in overrides if o.startswith("shard.packing=")]
    saved = json.loads(plan_path.read_text()) if plan_path.exists() else {"packing": (asked or shards.PACKINGS)[0]}
    if "counts" in saved or set(saved) == {"packing"}:
        return saved["packing"], dict(saved.get("counts", {}))
    return "contiguous", dict(saved)  # the older file: counts only, contiguous shards


class RdSweeper(Sweeper):
    """Basic sweeper + ``union`` of every codec's ``rd_<name>`` grid + stable job folders + skipping finished jobs.

    It derives from Hydra's abstract ``Sweeper``, not from ``BasicSweeper``: Hydra's plugin scan re-executes the
    modules of its core plugins, which would leave a subclass of the old ``BasicSweeper`` class behind.

    Parameters
    ----------
    max_batch_size : int or None
        Jobs handed to the launcher at once (progress is reported per batch).
    params : dict or None
        The grid, as the basic sweeper's ``hydra.sweeper.params`` (what ``rd_<name>.yaml`` sets).
    union : bool
        Run the union of every registered codec's ``rd_<name>`` grid (``sweep=all``).
    codecs : list of str or None
        With ``union``: only these codecs (default: every registered codec).
    exclude : list of str
        With ``union``: codecs to leave out.
    max_points : int or None
        Keep at most this many evenly spread points of each codec's grid (``sweep=small``).
    max_points_for : dict of str to int, optional
        With ``union``: a smaller ``max_points`` for the named codecs (the slow ones in ``sweep=small``).
    skip_done : bool
        Do not launch jobs whose folder already holds a finished job.
    dry_run : bool
        Write ``jobs.json`` (every job's folder and overrides) and launch nothing.
    allow_failures : bool
        Exit 0 even when a job failed (default: the sweep process exits 1 after its summary).
    """

    def __init__(
        self,
        max_batch_size: int | None = None,
        params: dict[str, str] | None = None,
        union: bool = False,
        codecs: Sequence[str] | None = None,
        exclude: Sequence[str] = (),
        max_points: int | None = None,
        max_points_for: dict[str, int] | None = None,
        skip_done: bool = True,
        dry_run: bool = False,
        allow_failures: bool = False,
    ) -> None:
        super().__init__()
        self.max_batch_size = max_batch_size
        self.params = dict(params or {})
        self.hydra_context = None
        self.config = None
        self.estimates: dict[str, float] = {}  # estimated CPU s of every job folder (shard_jobs)
        self.launcher = None
        self.union = bool(union)
        self.codecs = list(codecs) if codecs else None
        self.exclude = list(exclude or ())
        self.max_points = max_points
        self.max_points_for = dict(max_points_for or {})
        self.skip_done = skip_done
        self.dry_run = dry_run
        self.allow_failures = bool(allow_failures)
        self.skipped: list[str] = []

    def setup(self, *, hydra_context, task_function, config) -> None:
        from hydra.core.plugins import Plugins

        self.hydra_context = hydra_context
        self.config = config
        self.launcher = Plugins.instance().instantiate_launcher(
            hydra_context=hydra_context, task_function=task_function, config=config
        )

    # -- job list --------------------------------------------------------------------------------------
    def _parser(self) -> OverridesParser:
        return OverridesParser.create(config_loader=self.hydra_context.config_loader)

    def _grid(self, texts: Sequence[str]) -> list[list[str]]:
        """Cartesian product of parsed overrides (one list of ``k=v`` strings per point)."""
        overrides = self._parser().parse_overrides(list(texts))
        return _product(overrides) if overrides else [[]]

    def _rd_params(self, codec: str) -> dict[str, str] | None:
        """``hydra.sweeper.params`` of ``configs/sweep/rd_<codec>.yaml``, or None if that file is missing."""
        loader = self.hydra_context.config_loader
        option = f"rd_{codec}"
        if not loader.repository.group_exists("sweep") or option not in loader.get_group_options("sweep"):
            return None
        cfg = loader.load_configuration(
            config_name=self.config.hydra.job.config_name, overrides=[f"sweep={option}"], run_mode=RunMode.MULTIRUN
        )
        params = cfg.hydra.sweeper.get("params") or {}
        return {str(key): str(value) for key, value in OmegaConf.to_container(params).items()}

    def build_jobs(self, arguments: list[str]) -> list[tuple[str, list[str]]]:
        """Every job as ``(folder, overrides)``, folder relative to the sweep dir."""
        parsed: list[Override] = self._parser().parse_overrides(list(arguments))
        swept = [a for a, o in zip(arguments, parsed) if o.is_sweep_override()]
        codec_arg = [o for o in parsed if o.get_key_element() == "codec"]
        if not self.union:
            fixed = [a for a, o in zip(arguments, parsed) if not o.is_sweep_override()]
            return self._single_jobs(fixed, swept, codec_arg)
        fixed = [a for a, o in zip(arguments, parsed) if not o.is_sweep_override() and o.get_key_element() != "sweep"]
        return self._union_jobs(fixed, swept, codec_arg)

    def _single_jobs(self, fixed: list[str], swept: list[str], codec_arg: list[Override]) -> list[tuple[str, list[str]]]:
        """The jobs of one sweep: the grid of ``hydra.sweeper.params`` and the command line's swept overrides."""
        codec = self.config.codec.name if "codec" in self.config else "job"
        if codec_arg and not codec_arg[0].is_sweep_override():
            codec = codec_arg[0].get_value_element_as_str()
        params = [f"{k}={v}" for k, v in (self.params or {}).items()]
        jobs: list[tuple[str, list[str]]] = []
        for point in _evenly(self._grid(params + swept), self.max_points):
            names = [p for p in point if p.split("=", 1)[0] == "codec"]
            name = names[0].split("=", 1)[1] if names else codec
            jobs.append((job_folder(name, [p for p in point if p not in names]), [*fixed, *point]))
        return jobs

    def _union_codecs(self, codec_arg: list[Override]) -> list[str]:
        """The codecs of a union sweep: ``hydra.sweeper.codecs`` (or every registered one), narrowed by ``codec=``."""
        from mocapbench.codecs import codec_names

        names = self.codecs or codec_names()
        unknown = sorted(set(names) - set(codec_names()))
        if unknown:
            raise ValueError(f"hydra.sweeper.codecs names unregistered codecs {unknown}; registered: {codec_names()}")
        if codec_arg:  # `codec=a,b` on the command line restricts the union to those codecs
            wanted = [
                value
                for o in codec_arg
                for value in (o.sweep_string_iterator() if o.is_sweep_override() else [o.get_value_element_as_str()])
            ]
            names = [n for n in names if n in wanted]
        return names

    def _codec_selector(self, name: str) -> tuple[str, list[str]] | None:
        """How a union sweep selects one codec: ``(selector override, rd params)``, or None to leave it out."""
        if name in self.exclude:
            return None
        if name not in self.hydra_context.config_loader.get_group_options("codec"):
            log.warning("codec %s is registered but has no configs/codec/%s.yaml: left out", name, name)
            return None
        rd = self._rd_params(name)
        if rd is None:
            log.warning("codec %s has no configs/sweep/rd_%s.yaml: running its default config only", name, name)
            return f"codec={name}", []
        return f"sweep=rd_{name}", [f"{k}={v}" for k, v in rd.items()]

    def _union_jobs(self, fixed: list[str], swept: list[str], codec_arg: list[Override]) -> list[tuple[str, list[str]]]:
        """The jobs of a union sweep: every codec's own rd grid, times the command line's swept overrides."""
        names = self._union_codecs(codec_arg)
        if codec_arg:
            fixed = [a for a in fixed if not a.startswith("codec=")]
            swept = [a for a in swept if not a.startswith("codec=")]
        jobs: list[tuple[str, list[str]]] = []
        for name in names:
            chosen = self._codec_selector(name)
            if chosen is None:
                continue
            selector, params = chosen
            points = _evenly(self._grid(params), self.max_points_for.get(name, self.max_points))
            for point, extra in itertools.product(points, self._grid(swept)):
                jobs.append((job_folder(name, [*point, *extra]), [selector, *fixed, *point, *extra]))
        return jobs

    # -- shards ----------------------------------------------------------------------------------------
    _DATASET_KEYS = ("dataset", "data_dir", "shard")

    def _job_config(self, overrides: Sequence[str]) -> Any:
        """The composed config of a job, from its dataset and shard overrides only (what sizing needs)."""
        keep = [o for o in overrides
                if o.split("=", 1)[0].lstrip("+~").split(".", 1)[0] in self._DATASET_KEYS]
        return self.hydra_context.config_loader.load_configuration(
            config_name=self.config.hydra.job.config_name, overrides=keep, run_mode=RunMode.MULTIRUN
        )

    def shard_jobs(self, sweep_dir: Path, jobs: list[tuple[str, list[str]]]) -> list[tuple[str, list[str]]]:
        """Cut every job into shards (see the module docstring); ``shards.json`` keeps each config's count.

        ``shards.json`` is ``{"packing": ..., "counts": {folder: count}}``; a file of counts alone was written
        before the ``balanced`` packing existed, and its sweep resumes with the ``contiguous`` one
        (:mod:`mocapbench.experiments.shards`).
        """
        from mocapbench.experiments import cost, shards

        plan_path = sweep_dir / SHARDS_FILE
        packing, plan = _saved_plan(plan_path, jobs)
        costs = cost.load_costs()
        catalogues: dict[tuple[str, ...], Any] = {}
        out: list[tuple[str, list[str]]] = []
        self.estimates = {}
        for folder, overrides in jobs:
            refs, shard_cfg, dataset = self._job_catalogue(catalogues, folder, overrides)
            own = cost.for_dataset(costs, dataset)  # a dataset's own measured costs, where it has them
            per_frame, per_clip = cost.cpu_cost(own, folder)
            if folder not in plan:
                fixed = [o for o in overrides if o.split("=", 1)[0] == "shard.count"]
                if fixed:
                    plan[folder] = int(shard_cfg.count)
                else:
                    plan[folder] = shards.shard_count([r.frames for r in refs], per_frame, shard_cfg.max_cpu_s,
                                                      per_clip, packing)
            count = plan[folder]
            job_costs = cost.job_costs(own, folder, [r.frames for r in refs], count, packing)
            out.extend(self._shards_of(folder, overrides, count, packing, job_costs))
        plan_path.write_text(json.dumps({"packing": packing, "counts": plan}, indent=1, sort_keys=True))
        return out

    def _job_catalogue(self, catalogues: dict, folder: str, overrides: Sequence[str]) -> tuple[list, Any, str]:
        """``(clip refs, shard config, dataset name)`` of a job's dataset, composed once per dataset and shard
        overrides."""
        from mocapbench.experiments import datasets

        key = tuple(o for o in overrides if o.split("=", 1)[0].split(".", 1)[0] in self._DATASET_KEYS)
        if key not in catalogues:
            cfg = self._job_config(overrides)
            spec = OmegaConf.to_container(cfg.dataset, resolve=True)
            try:
                refs = datasets.catalogue(spec)
            except Exception as error:  # noqa: BLE001 - the job itself reports a bad dataset
                log.warning("dataset of %s: %s (one shard; the job will say why)", folder, error)
                refs = []
            catalogues[key] = (refs, cfg.shard, str(spec.get("name", "")))
        return catalogues[key]

    def _shards_of(self, folder: str, overrides: list[str], count: int, packing: str,
                   job_costs: Sequence[float]) -> list[tuple[str, list[str]]]:
        """The ``count`` shards of one job, each with its estimated CPU seconds recorded in :attr:`estimates`."""
        from mocapbench.experiments import shards

        if count == 1:
            self.estimates[folder] = job_costs[0]
            return [(folder, [o for o in overrides if not o.startswith("shard.count=")])]
        base = [o for o in overrides if o.split("=", 1)[0] not in ("shard.index", "shard.count", "shard.packing")]
        out = []
        for index in range(count):
            out.append((shards.shard_folder(folder, index, count),
                        [*base, f"shard.index={index}", f"shard.count={count}", f"shard.packing={packing}"]))
            self.estimates[out[-1][0]] = job_costs[index] if index < len(job_costs) else 0.0
        return out

    # -- running ---------------------------------------------------------------------------------------
    def validate_batch_is_legal(self, batch: Sequence[Sequence[str]]) -> None:
        """Compose one job of each shape of the batch before launching any, to fail early on a bad override.

        A shape is the set of overridden keys with the values of the config-group overrides (``sweep=rd_acl``,
        ``dataset=cmu_test``): jobs of one shape differ only in the values of plain fields (a step, a rank), which
        compose the same way, and the job itself reports a value its codec refuses. Hydra's own check composed
        every job (a fifth of a second each, in the sweep's process before the first job started).
        """
        repository = self.hydra_context.config_loader.repository
        shapes: set[tuple[str, ...]] = set()
        sample = []
        for overrides in batch:
            shape = []
            for override in overrides:
                key = override.split("=", 1)[0]
                if key == "hydra.sweep.subdir":
                    continue
                group = key.lstrip("+~").split("@", 1)[0]
                shape.append(override if "." not in group and repository.group_exists(group) else key)
            if tuple(sorted(shape)) not in shapes:
                shapes.add(tuple(sorted(shape)))
                sample.append(overrides)
        super().validate_batch_is_legal(sample)

    def sweep(self, arguments: list[str]) -> Any:
        assert self.config is not None and self.launcher is not None and self.hydra_context is not None
        sweep_dir = Path(self.config.hydra.sweep.dir)
        sweep_dir.mkdir(parents=True, exist_ok=True)
        OmegaConf.save(self.config, sweep_dir / "multirun.yaml")
        jobs = self.shard_jobs(sweep_dir, self.build_jobs(arguments))
        seen: OrderedDict[str, list[str]] = OrderedDict()
        for folder, overrides in jobs:
            if folder in seen:
                raise ValueError(f"two jobs map to the same folder {folder!r}: {seen[folder]} and {overrides}")
            seen[folder] = overrides
        todo, launched = [], []
        for folder, overrides in jobs:
            if self.skip_done and is_job_done(sweep_dir / folder):
                self.skipped.append(folder)
                continue
            todo.append([*overrides, f"hydra.sweep.subdir='{folder}'"])
            launched.append(folder)
            # A stale job.json of an earlier failed run would read as finished to the progress monitor.
            (sweep_dir / folder / JOB_FILE).unlink(missing_ok=True)
        (sweep_dir / "jobs.json").write_text(json.dumps([{"folder": f, "overrides": o} for f, o in jobs], indent=1))
        if self.dry_run:
            return []
        order = longest_first(launched, self.estimates)
        todo, launched = [todo[i] for i in order], [launched[i] for i in order]
        from mocapbench.experiments.cost import makespan
        from mocapbench.experiments.sweep_progress import JobMonitor, format_duration, format_summary, summarize

        size = self.max_batch_size or len(todo) or 1
        batches = [todo[i : i + size] for i in range(0, len(todo), size)]
        returns = []
        index = 0
        start = time.perf_counter()
        workers = int(OmegaConf.select(self.config, "hydra.launcher.n_jobs", default=1) or 1)
        estimates = {folder: self.estimates.get(folder, 0.0) for folder in launched}
        print(f"sweep {sweep_dir}: {len(jobs)} jobs, {len(self.skipped)} already done, {len(todo)} to run; "
              f"estimated {format_duration(makespan(list(estimates.values()), workers))} on {workers} worker(s) "
              f"({sum(estimates.values()) / 60:.1f} CPU-min, costs of configs/costs.json)", flush=True)
        # One line per finished job with an ETA (the launcher only returns when a whole batch is done).
        with JobMonitor(sweep_dir, launched, estimates=estimates, workers=workers):
            for batch in batches:
                tic = time.perf_counter()
                self.validate_batch_is_legal(batch)
                log.debug("validated %d jobs in %.2f s", len(batch), time.perf_counter() - tic)
                results = self.launcher.launch(batch, initial_job_idx=index)
                for result in results:
                    _ = result.return_value  # re-raises a job's exception (jobs catch their own errors)
                index += len(batch)
                returns.append(results)
        summary = summarize(sweep_dir, launched, self.skipped, time.perf_counter() - start)
        print(format_summary(summary, self.allow_failures), flush=True)
        (sweep_dir / "summary.json").write_text(json.dumps(
            {"done": summary.done, "failed": summary.failed, "missing": summary.missing, "skipped": summary.skipped,
             "reasons": dict(summary.reasons), "seconds": summary.seconds}, indent=1))
        if not summary.ok and not self.allow_failures:
            # Hydra has no exit code for a sweep whose jobs failed: end the process with one after the summary.
            sys.exit(1)
        return returns
