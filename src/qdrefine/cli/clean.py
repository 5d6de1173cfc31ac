"""``qdrefine clean STORE``: remove what interrupted or killed runs left next to a store."""

from __future__ import annotations

import argparse

from . import _common

HELP = "remove the temporary stores that killed or interrupted runs left next to a store"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser)
    parser.epilog = ("A run writing OUT.zarr (qdrefine refine --dask, qdrefine convert) works "
                     "in a temporary store .OUT.zarr~HOST~PID~TOKEN.tmp next to it. A killed "
                     "run leaves it behind; the next run writing OUT.zarr removes those whose "
                     "process is gone, and so does this command. Example: qdrefine clean "
                     "out.zarr; qdrefine clean s3://bucket/out.zarr --all")
    parser.add_argument("store", metavar="STORE", help="the store (path or URL) whose "
                        "temporaries to remove; the store itself is never touched")
    parser.add_argument("--all", action="store_true", dest="everything",
                        help="also remove temporaries of runs that may still be going (other "
                             "hosts, live processes): only when no run writes STORE")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        from .. import store

        removed = store.clean(args.store, everything=args.everything)
        if not args.quiet:
            for url in removed:
                print(f"removed {url}")
            if not removed:
                print(f"{args.store}: no temporaries to remove")
    return 0
