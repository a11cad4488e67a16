"""Commands whose items are experiments (``fit``, ``simulate``), resumable as ``detect`` is.

Each finished experiment's result is kept in the run's working folder
(:class:`notchfit.io.ResumableRun`, ``OUT/.notchfit-resume-<command>/``) as it
completes: its record holds the content hash of the experiment's data as read
(points or angles, tensions, geometry, samples, σ) and the hash of the
command's options with notchfit's version; beside it the result itself
(pickled, read back only by the same version of notchfit with the same
options). ``--resume`` runs only the experiments not kept, or whose data or
options changed since; the tables and figures are then written from every
experiment's result and moved into ``OUT`` at once, as an uninterrupted run
writes them.
"""

from __future__ import annotations

import pickle

from .. import io
from .._version import __version__
from ..batch import BatchResult, ItemResult, run_batch
from ._common import check_out_dir

_VALUE = ".pickle"


def add_resume_option(parser, unit: str) -> None:
    """``--resume``: continue the interrupted run in ``--out``."""
    parser.add_argument("--resume", action="store_true",
                        help=f"continue the interrupted run in --out: only the {unit} not yet done, or whose data "
                             "or options changed since, are run")


def check_out(args, record: str) -> None:
    """The output folder's checks before the input is read (:func:`check_out_dir`); with
    ``--resume``, that it holds an interrupted run of this command (else exit 2)."""
    if args.resume:
        check_out_dir(args.out, args.input)
        io.check_resumable(args.out, args.command, [record])
    else:
        check_out_dir(args.out, args.input, outputs=[record], force=args.force)


def open_run(args, outputs, unit: str) -> io.ResumableRun:
    """The command's :class:`~notchfit.io.ResumableRun` in ``--out``."""
    return io.ResumableRun(args.out, name=args.command, input_path=args.input, resume=args.resume,
                           force=args.force, outputs=outputs, unit=unit)


def run_resumable(run_, func, items: list[dict], keys: list[str], *, option_keys, args) -> BatchResult:
    """:func:`~notchfit.batch.run_batch` over the items not kept by an interrupted run; each result
    kept as it arrives.

    Parameters
    ----------
    run_ : notchfit.io.ResumableRun
        The command's run (:func:`open_run`); its ``unit`` names the items in the notes and the progress.
    func : callable
        The batch function (``func(item) -> value``; the value must pickle).
    items : list of dict
        One batch item per experiment: its data and options.
    keys : list of str
        The experiments' names.
    option_keys : sequence of str
        The keys of an item that are the command's options (hashed with
        notchfit's version; a key an item lacks, such as the point loss of an
        angle experiment, is not among its options); the other keys are the
        experiment's data (its content hash).
    args : argparse.Namespace
        ``command`` (the progress's label), ``jobs``, ``scheduler`` and ``resume``.

    Returns
    -------
    BatchResult
        Every experiment's outcome in input order, its value read back for
        those kept now or by the interrupted run; ``seconds`` of this run's batch.
    """
    options = [io.options_sha256({"notchfit": __version__, **{k: it[k] for k in option_keys if k in it}}) for it in items]
    content = [io.ContentHash(io.options_sha256({k: v for k, v in it.items() if k not in option_keys}))
               for it in items]
    kept = run_.reconcile({k: (c, o) for k, c, o in zip(keys, content, options)})
    todo = [i for i, k in enumerate(keys) if k not in kept]
    if args.resume:
        print(f"  resuming the interrupted run: {len(kept)} of {len(keys)} {run_.unit} kept, {len(todo)} to run")

    def keep(i: int, r) -> None:
        if r.ok:                  # failed items are not kept: a resumed run tries them again
            k = todo[i]
            run_.keep(keys[k], input_sha256=content[k], options_sha256=options[k], value={"seconds": r.seconds},
                      own_files={_VALUE: pickle.dumps(r.value, protocol=pickle.HIGHEST_PROTOCOL)})

    res = run_batch(func, [items[i] for i in todo], keys=[keys[i] for i in todo], jobs=args.jobs,
                    scheduler=args.scheduler, desc=args.command, unit=run_.unit, on_result=keep)
    failed = {r.key: r for r in res.failures}
    out = [failed[k] if k in failed else
           ItemResult(key=k, ok=True, value=pickle.loads(run_.own_file(k, _VALUE).read_bytes()),
                      seconds=run_.record(k)["value"]["seconds"]) for k in keys]
    return BatchResult(items=tuple(out), seconds=res.seconds)
