"""``swarm-mj view FILE.rrd``: the recording in the desktop viewer, or in a browser (``--web``)."""

from __future__ import annotations

import argparse

from ..output.viewer import DEFAULT_PORT


def add_parser(sub) -> None:
    p = sub.add_parser(
        "view",
        help="open a recording (.rrd) in the Rerun viewer, or serve it to a browser",
        description="Open a recording in the desktop Rerun viewer (needs a display). With --web, "
        "serve Rerun's web viewer with the recording on 127.0.0.1 and print the URL "
        "(reach it through an SSH tunnel from another machine); Ctrl-C stops it.",
    )
    p.add_argument("file", metavar="FILE.rrd", help="the recording, as written by 'swarm-mj run'")
    add_web_arguments(p)
    p.set_defaults(func=main)


def add_web_arguments(p: argparse.ArgumentParser) -> None:
    """``--web`` and ``--port``, shared with ``swarm-mj run``."""
    p.add_argument(
        "--web",
        action="store_true",
        help="serve Rerun's web viewer with the recording on localhost and wait for Ctrl-C",
    )
    p.add_argument(
        "--port",
        type=int,
        default=DEFAULT_PORT,
        help=f"port of the web page (default {DEFAULT_PORT}); the recording is served on PORT+1",
    )


def main(args: argparse.Namespace) -> int:
    from ..output.viewer import check_recording, open_desktop, serve_until_interrupted

    path = check_recording(args.file)
    if args.web:
        return serve_until_interrupted(path, args.port)
    pid = open_desktop(path)
    print(f"opened {path} in the Rerun viewer (pid {pid})")
    return 0
