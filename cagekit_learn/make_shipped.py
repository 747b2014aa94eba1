"""Training the shipped models (``make models``): real data from Debian packages, seeded.

``python -m cagekit_learn.make_shipped NAME`` trains the shipped model ``NAME`` from its
recipe (:data:`RECIPES`) and writes ``cagekit_learn/models/NAME.pt`` and ``NAME.json``
(:mod:`cagekit_learn.shipped`) atomically:

1. the data: the recipe's kinds of Debian's ``sweethome3d-furniture`` (its three furniture
   catalogs; Scopia is never used), split by
   :func:`cagekit.datasets.sweethome3d.held_out_split` (one model in ``every`` of each
   kind held out for the benchmark, ``benchmarks/bench_learn_real.py``), linked into
   ``RUN_DIR/train`` as ``000.obj, 001.obj, ...`` in that order; with the recipe's
   ``amplify`` (``"all"``: every ordered pair), the variations of them that
   :func:`cagekit.batch.amplify.amplify` accepts (per-pair cage optimisation, its
   plausibility filter; made in ``RUN_DIR/amplified``) are linked after them, in the
   manifest's order (the classical method as a teacher: more shapes of the kind);
2. the first steps' fingerprint: a run of :data:`FINGERPRINT_STEPS` steps with the same
   config, its weights' SHA-256 and its last losses (``tests/learn/test_shipped.py``
   reruns it);
3. the training: ``recipe["steps"]`` steps of :func:`cagekit_learn.train.train` (seed 0,
   batch 8, the default model), then the weights exported without the optimiser.

Everything random is a function of the seed (:mod:`cagekit_learn.train`), so on one kind
of machine (torch version, CPU instruction set, thread count, all recorded) the run is
reproduced bit for bit. A recipe with ``"kernels": True`` (both shipped ones: ``chairs``'
6,000 steps take 16 minutes on 2 cores with them) computes mean value coordinates with
the compiled kernels of :mod:`cagekit_learn.coords`, so a change to the kernels changes its
fingerprint; they sum each chunk of points apart and the chunks in order, so a run is
reproduced bit for bit at the same thread count. Without it, both runs use the torch graph
(:func:`~cagekit_learn.coords.compiled_kernels` off), the reference the kernels are tested
against, which a change to the kernels leaves alone.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import os
import shutil
import sys
from pathlib import Path

import torch

from cagekit.datasets.sweethome3d import FURNITURE_CATALOGS, SEAT_KINDS, held_out_split, models
from cagekit.errors import InputError
from cagekit.io.files import atomic_output
from cagekit_learn.checkpoint import load_checkpoint, save_checkpoint
from cagekit_learn.coords import compiled_kernels
from cagekit_learn.shipped import MODELS_DIR
from cagekit_learn.train import TrainConfig, TrainResult, load_model, train

__all__ = ["RECIPES", "FINGERPRINT_STEPS", "training_shapes", "training_folder",
           "amplified_shapes", "config_of", "weights_sha256", "machine", "first_steps",
           "make_model"]

#: what each shipped model is trained on, and for how long
RECIPES = {
    "chairs": {
        "description": "seats (chairs, armchairs, sofas, stools and benches) of Debian's "
                       "sweethome3d-furniture, its three furniture catalogs",
        "kinds": list(SEAT_KINDS),
        "every": 4,
        "steps": 6000,
        "seed": 0,
        "alpha_parts": 200.0,
        "kernels": True,
    },
    "tables": {
        "description": "tables of Debian's sweethome3d-furniture, its three furniture "
                       "catalogs, and the variations cagekit amplify makes of them",
        "kinds": ["table"],
        "every": 4,
        "steps": 3000,
        "seed": 0,
        "amplify": "all",
        "alpha_parts": 200.0,
        "kernels": True,
    },
}
#: steps of the fingerprint run
FINGERPRINT_STEPS = 2


def training_shapes(name: str, cache: str = "out/sweethome3d") -> tuple[list, list]:
    """The recipe's training and held-out models: two lists of (kind, Model)."""
    recipe = _recipe(name)
    return held_out_split(models(FURNITURE_CATALOGS, cache=cache), recipe["kinds"],
                          recipe["every"])


def training_folder(shapes: list, folder: str | os.PathLike) -> Path:
    """A folder of links ``000.obj, 001.obj, ...`` to the shapes' OBJ files, in order.

    Parameters
    ----------
    shapes : list of (kind, Model)
    folder : str or os.PathLike
        Emptied of earlier links first.

    Returns
    -------
    Path
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("*.obj"):
        old.unlink()
    for i, (_, model) in enumerate(shapes):
        (folder / f"{i:03d}.obj").symlink_to(os.path.abspath(model.path))
    return folder


def amplified_shapes(folder: str | os.PathLike, out_dir: str | os.PathLike, pairs: str,
                     seed: int = 0) -> list[dict]:
    """Link the accepted variations of a training folder's shapes into it, after them.

    Parameters
    ----------
    folder : str or os.PathLike
        A folder of ``000.obj, 001.obj, ...`` (:func:`training_folder`).
    out_dir : str or os.PathLike
        Where :func:`cagekit.batch.amplify.amplify` writes (a rerun resumes).
    pairs : str
        Its ``pairs`` (``"all"``: every ordered pair of the folder's shapes).
    seed : int

    Returns
    -------
    list of dict
        Per accepted variation, in the manifest's order: ``source``, ``target`` (the
        folder's names) and ``file`` (the link's name).
    """
    from cagekit.batch.amplify import amplify  # the core's batch layer, only when asked

    folder = Path(folder)
    rows = amplify(str(folder), str(out_dir), pairs=pairs, seed=seed, drop_rejected=True)
    start = len(list(folder.glob("*.obj")))
    accepted: list[dict] = []
    for row in rows:
        if row["status"] != "ok":
            continue
        link = folder / f"{start + len(accepted):03d}.obj"
        link.symlink_to(os.path.abspath(Path(out_dir) / "variations" / row["output"]))
        accepted.append({"source": row["source"], "target": row["target"],
                         "file": link.name})
    return accepted


def config_of(name: str, data: str | os.PathLike, run_dir: str | os.PathLike,
              steps: int) -> TrainConfig:
    """The training config of a shipped model (defaults but for data, seed and steps, and
    the part-affinity term: off unless the recipe gives its ``alpha_parts``, as the shipped
    models were trained before it)."""
    recipe = _recipe(name)
    return TrainConfig(data=str(data), run_dir=str(run_dir), epochs=1_000_000,
                       seed=recipe["seed"], max_steps=int(steps),
                       alpha_parts=float(recipe.get("alpha_parts", 0.0)))


def weights_sha256(state_dict: dict) -> str:
    """SHA-256 of a state dict's tensors (names sorted, float32 bytes): equal only when
    every weight is equal bit for bit."""
    digest = hashlib.sha256()
    for key in sorted(state_dict):
        digest.update(key.encode())
        digest.update(state_dict[key].detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


def machine() -> dict:
    """What a bit-for-bit comparison depends on: torch's version, threads and instruction
    set, and the CPU model as LLVM names it (``icelake-server``, ``znver5``): torch's
    matrix products pick kernels by CPU model too, not only by instruction set."""
    import llvmlite.binding  # numba's, installed with the core

    return {"torch": torch.__version__, "threads": torch.get_num_threads(),
            "cpu_capability": torch.backends.cpu.get_cpu_capability(),
            "cpu": llvmlite.binding.get_host_cpu_name()}


def _reference_train(name: str, config: TrainConfig, progress: bool) -> TrainResult:
    """:func:`~cagekit_learn.train.train` through the reference torch graph, or the
    compiled kernels where the recipe says so (see the module), as both the fingerprint
    and the shipped run train."""
    with compiled_kernels(bool(_recipe(name).get("kernels", False))):
        return train(config, progress=progress)


def first_steps(name: str, data: str | os.PathLike, run_dir: str | os.PathLike) -> dict:
    """Train :data:`FINGERPRINT_STEPS` steps of the recipe; the weights' hash and losses.

    Returns
    -------
    dict
        ``steps``, ``weights_sha256``, ``losses`` (the last step's terms) and
        :func:`machine`.
    """
    result = _reference_train(name, config_of(name, data, run_dir, FINGERPRINT_STEPS),
                              False)
    return {"steps": result.step, "weights_sha256": weights_sha256(result.model.state_dict()),
            "losses": {k: float(v) for k, v in result.last_losses.items()}, **machine()}


def make_model(name: str, run_dir: str | os.PathLike, steps: int | None = None,
               cache: str = "out/sweethome3d",
               out_dir: str | os.PathLike = MODELS_DIR) -> Path:
    """Train the shipped model ``name`` and write ``out_dir/NAME.pt`` and ``NAME.json``.

    Parameters
    ----------
    name : str
        A key of :data:`RECIPES`.
    run_dir : str or os.PathLike
        Working folder (the training links, the runs).
    steps : int, optional
        Default: the recipe's.
    cache : str
        Where the catalogs are unpacked (:func:`cagekit.datasets.sweethome3d.models`).
    out_dir : str or os.PathLike
        Where the model goes (default the package's :data:`MODELS_DIR`).

    Returns
    -------
    Path
        The checkpoint written.
    """
    recipe = _recipe(name)
    steps = int(recipe["steps"] if steps is None else steps)
    run_dir = Path(run_dir)
    train_shapes, held_out = training_shapes(name, cache)
    data = training_folder(train_shapes, run_dir / "train")
    # every run starts afresh: amplify would resume a variations folder an earlier run (of
    # other code) left, and its manifest would not be what this code accepts
    for old in ("amplified", "first_steps", "run"):
        shutil.rmtree(run_dir / old, ignore_errors=True)
    variations = (amplified_shapes(data, run_dir / "amplified", recipe["amplify"],
                                   recipe["seed"]) if recipe.get("amplify") else [])
    fingerprint = first_steps(name, data, run_dir / "first_steps")
    result = _reference_train(name, config_of(name, data, run_dir / "run", steps), True)
    payload = load_checkpoint(run_dir / "run")
    exported = {k: payload[k] for k in ("model", "model_config", "config", "step", "epoch",
                                        "skipped")}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    checkpoint = out_dir / f"{name}.pt"
    save_checkpoint(checkpoint, exported)
    load_model(checkpoint)  # refuse to ship what cannot be loaded
    record = {
        "name": name, "description": recipe["description"],
        "command": f"make models (python -m cagekit_learn.make_shipped {name})",
        "data": {"package": "sweethome3d-furniture", "catalogs": list(FURNITURE_CATALOGS),
                 "kinds": recipe["kinds"], "held_out_every": recipe["every"],
                 "train": [_entry(k, m) for k, m in train_shapes],
                 "held_out": [_entry(k, m) for k, m in held_out],
                 "amplified": variations},
        "training": {"steps": result.step, "skipped": result.skipped,
                     "seconds": round(result.seconds, 1),
                     "pairs_per_second": round(result.pairs_per_second, 2),
                     "config": payload["config"], **machine(),
                     "date": datetime.date.today().isoformat()},
        "first_steps": fingerprint,
        "licence": "the weights are derived from the shapes listed under data.train, each "
                   "under its own licence (CC0 or CC BY 3.0: credit its creator)",
    }
    with atomic_output(out_dir / f"{name}.json") as tmp, open(tmp, "w") as handle:
        json.dump(record, handle, indent=1)
        handle.write("\n")
    return checkpoint


def _entry(kind, model) -> dict:
    return {"kind": kind, "catalog": model.catalog, "name": model.name,
            "creator": model.creator, "license": model.license,
            "file": os.path.basename(model.path)}


def _recipe(name: str) -> dict:
    if name not in RECIPES:
        raise InputError(f"{name}: no recipe (recipes: {', '.join(sorted(RECIPES))})")
    return RECIPES[name]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Train a shipped model from its recipe.")
    parser.add_argument("name", choices=sorted(RECIPES))
    parser.add_argument("--run-dir", default=None, help="default out/models/NAME")
    parser.add_argument("--steps", type=int, default=None, help="default: the recipe's")
    parser.add_argument("--out-dir", default=str(MODELS_DIR))
    args = parser.parse_args(argv)
    try:
        path = make_model(args.name, args.run_dir or f"out/models/{args.name}", args.steps,
                    out_dir=args.out_dir)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
