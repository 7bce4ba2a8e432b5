"""The ``inkwarp`` command line.

Each command lives in a module of this package that defines ``add_parser(subparsers)``
(which registers the command and sets ``func``). Exit codes: 0 success, 2 bad input (one
clear message, no traceback), 1 internal error.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import os
import signal
import sys
import threading
import traceback
import warnings

from inkwarp.cli._common import UNWINDING, prefixed, problem_parts
from inkwarp.errors import InkwarpError, InternalError, OutputWriteError, PastEndWarning, SceneError, WorkerLostError

# The command modules, in the order `inkwarp --help` lists them.
COMMANDS: list[str] = ["new", "render", "field", "validate", "schema", "demo", "edit", "compare", "transfer",
                       "frame", "track"]

EPILOG = """\
examples:
  inkwarp new character.psd -o character.json --drawing tracing.svg
  inkwarp render examples/face/scene.json -o face.mp4
  inkwarp render examples/face/scene.json --time 1.0 -o frame.png
  inkwarp validate examples/face/scene.json
  inkwarp demo -o out
  inkwarp edit examples/cat/scene.json
  inkwarp compare examples/checkerboard-hole/with-hole.json -o sheet.png
  inkwarp transfer --source examples/face/scene.json --target cat.json -o cat_animated.json
  inkwarp track actor.mp4 --scene actor.json -o actor-tracked.json

Run 'inkwarp COMMAND --help' for a command's options. Exit status: 0 success, 2 bad input
(the message names the file, the place in it and the fix), 1 internal error, 3 a solve that
did not converge (render and field with --strict).
"""


def build_parser() -> argparse.ArgumentParser:
    from inkwarp import __version__

    parser = argparse.ArgumentParser(
        prog="inkwarp",
        description="Animate a still image by animating a drawing traced over it.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"inkwarp {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"inkwarp.cli.{name}").add_parser(subparsers)
    parser.set_defaults(commands=subparsers.choices)
    return parser


def error_message(err: BaseException) -> str:
    """The one line the command line prints for a bad-input error.

    A :class:`~inkwarp.SceneError` becomes ``FILE: JSON.PATH: what is wrong and the fix``
    (each part left out when unknown or already in the message), with a count of the
    further problems that ``inkwarp validate`` lists.
    """
    if isinstance(err, SceneError):
        problems = list(err.problems or [])
        path, message = problem_parts(problems[0]) if problems else (err.path, str(err))
        if not message:
            message = str(err)
        line = prefixed(message, path)
        line = prefixed(line, err.file)
        if len(problems) > 1:
            more = len(problems) - 1
            where = f"inkwarp validate {err.file}" if err.file else "inkwarp validate"
            line += f" (and {more} more problem{'s' if more > 1 else ''}: '{where}' lists all)"
        return " ".join(line.split())
    if isinstance(err, FileNotFoundError) and err.filename:
        # (Python's own words lower-cased; inkwarp's own, such as "the source scene does not exist", kept.)
        why = err.strerror if err.strerror and err.strerror != os.strerror(errno.ENOENT) else "no such file or directory"
        return f"{err.filename}: {why}"
    if isinstance(err, OSError) and err.filename and err.strerror:
        return f"{err.filename}: {err.strerror}"
    return " ".join(str(err).split()) or type(err).__name__


class Terminated(BaseException):
    """SIGTERM, or SIGHUP (the terminal closed, an SSH session lost), raised where the program
    is, so that writers delete their partial output. ``signum`` is the signal's number."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _on_signal(signum: int, frame: object) -> None:
    # A closed terminal often sends SIGHUP twice (the shell's, then the kernel's): the second
    # must not land in the cleanup the first starts.
    for number in UNWINDING:
        signal.signal(number, signal.SIG_IGN)
    raise Terminated(signum)


@contextlib.contextmanager
def _sigterm_unwinds():
    """While a command runs, SIGTERM and SIGHUP unwind the stack like Ctrl-C does (their
    default action would kill the process with its temporary files in place)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {number: signal.signal(number, _on_signal) for number in UNWINDING
                if signal.getsignal(number) is not signal.SIG_IGN}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _stdout_closed() -> bool:
    """Whether standard output is a pipe whose reader has gone (it polls as an error)."""
    import select

    try:
        poll = select.poll()
        poll.register(sys.stdout.fileno(), select.POLLOUT)
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poll.poll(0))
    except (OSError, ValueError, AttributeError):  # (a stdout with no descriptor)
        return False


class _Stdout:
    """Standard output during a command: a write that fails for a disk's reason (a full
    disk, a quota) says it was standard output, not one of the command's files."""

    def __init__(self, inner: object) -> None:
        self._inner = inner

    def _failed(self, err: OSError) -> OSError:
        from inkwarp.video import DISK_FULL, disk_failure

        # (not EIO: a terminal that hung up)
        return disk_failure("standard output", err) if err.errno in DISK_FULL else err

    def write(self, text: str) -> int:
        try:
            return self._inner.write(text)  # type: ignore[attr-defined,no-any-return]
        except OSError as err:
            raise self._failed(err) from None

    def flush(self) -> None:
        try:
            self._inner.flush()  # type: ignore[attr-defined]
        except OSError as err:
            raise self._failed(err) from None

    def __getattr__(self, name: str) -> object:
        return getattr(self._inner, name)


@contextlib.contextmanager
def _stdout_said() -> object:
    """Within: standard output as :class:`_Stdout`, flushed at the end (so that a failing
    write is seen here, not at exit)."""
    inner = sys.stdout
    if inner is None:  # started without a standard output (`>&-`): prints go nowhere
        yield
        return
    sys.stdout = _Stdout(inner)  # type: ignore[assignment]
    try:
        yield
        sys.stdout.flush()
    finally:
        sys.stdout = inner


def _unwritten(err: OSError, output: object) -> OSError:
    """A full disk, a quota or a file-size limit without a file name (met while writing a
    file already open) as the error naming the command's output, where it has one (an
    input's read error, EIO, is left as it is)."""
    from inkwarp.video import DISK_FULL, disk_failure

    if err.filename is not None or not isinstance(output, str) or isinstance(err, OutputWriteError) or err.errno not in DISK_FULL:
        return err
    return disk_failure(f"{output}: the file", err)


def _dash_values_joined(argv: list[str]) -> list[str]:
    """``--frames -5:3`` as ``--frames=-5:3`` and ``--time -1e-3`` as ``--time=-1e-3``: a
    range or a number with an exponent (or ``-inf``) starting with a minus sign looks like
    an option to the parser, which would refuse it without the option's own message."""
    out: list[str] = []
    for arg in argv:
        if out and out[-1] == "--frames" and arg.startswith("-") and ":" in arg:
            out[-1] = f"--frames={arg}"
        elif out and out[-1] == "--time" and arg.startswith("-") and _is_number(arg):
            out[-1] = f"--time={arg}"
        else:
            out.append(arg)
    return out


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def main(argv: list[str] | None = None) -> int:
    import inkwarp

    if signal.getsignal(signal.SIGINT) is inkwarp._interrupted_while_starting:
        # The imports are done: from here Ctrl+C is the command's (exit 130, its own words).
        signal.signal(signal.SIGINT, signal.default_int_handler)
    parser = build_parser()
    words = _dash_values_joined(sys.argv[1:] if argv is None else [str(a) for a in argv])
    args, extra = parser.parse_known_args(words)
    if extra:
        # The command's own usage and name (`inkwarp render ... --fps 12`), unless the word
        # came before the command (`inkwarp --bogus render ...`).
        before = words[: words.index(args.command)] if args.command in words else words
        owner = parser if any(word in before for word in extra) else args.commands.get(args.command, parser)
        owner.error(f"unrecognized arguments: {' '.join(extra)}")
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return 2
    if isinstance(getattr(args, "output", None), str) and not args.output.strip():
        # An unset shell variable (-o "$OUT"): not "here", which would fill the directory.
        print(f"inkwarp {args.command}: error: -o is empty; give the file or directory to write",
              file=sys.stderr)
        return 2
    if getattr(args, "output", None) == "-":
        # Not standard output, as "-" is elsewhere: it would be a file or folder named "-".
        hint = {"render": "name the file or directory to write, such as out.mp4 or frames/",
                "schema": "leave -o out to print the schema"}.get(
                    args.command, "name the file to write")
        print(f"inkwarp {args.command}: error: -o -: inkwarp {args.command} writes files, not "
              f"standard output; {hint}", file=sys.stderr)
        return 2
    try:
        with _sigterm_unwinds(), _stdout_said(), warnings.catch_warnings():
            # A --time past the scene's end is said in each command's own words
            # (_common.warn_past_end), not as the API's warning again.
            warnings.simplefilter("ignore", PastEndWarning)
            return int(args.func(args) or 0)
    except InternalError as err:
        print(f"inkwarp {args.command}: {err}", file=sys.stderr)
        return 1
    except BrokenPipeError as err:
        # The reader of the output went away (`inkwarp validate ... | head -1`): stop without
        # a word, as command-line tools do, and let nothing flush into the closed pipe at exit.
        # Another pipe breaking (an encoder's) is a failing system, said below.
        if _stdout_closed():
            with contextlib.suppress(OSError, ValueError, AttributeError):
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 128 + signal.SIGPIPE
        print(f"inkwarp {args.command}: error: {error_message(err)}", file=sys.stderr)
        return 1
    except (OutputWriteError, WorkerLostError) as err:
        # Not the user's input and not a bug: the machine could not take the output, or a
        # farm's worker died.
        print(f"inkwarp {args.command}: error: {error_message(err)}", file=sys.stderr)
        return 1
    except (InkwarpError, ValueError, FileNotFoundError, PermissionError, IsADirectoryError,
            NotADirectoryError) as err:
        if isinstance(err, ValueError) and _a_bug(err):
            return _internal_error(args.command)
        print(f"inkwarp {args.command}: error: {error_message(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"inkwarp {args.command}: interrupted", file=sys.stderr)
        return 130
    except Terminated as err:
        hung_up = err.signum == getattr(signal, "SIGHUP", None)
        with contextlib.suppress(OSError, ValueError):  # (a closed terminal takes no more)
            print(f"inkwarp {args.command}: {'hung up' if hung_up else 'terminated'}", file=sys.stderr)
        return 128 + err.signum
    except OSError as err:
        # Not the user's input and not a bug: a full disk, ffmpeg dying.
        print(f"inkwarp {args.command}: error: {error_message(_unwritten(err, getattr(args, 'output', None)))}",
              file=sys.stderr)
        return 1
    except Exception:  # noqa: BLE001 - the last line of defence: report the bug, exit 1
        return _internal_error(args.command)


#: The words of ValueErrors that Python and numpy raise for a program's own mistakes, never
#: for a scene's or an argument's (inkwarp says those in its own words): such an error is a
#: bug, reported as one (exit 1, with its traceback), not as bad input (exit 2), which a
#: render farm would not retry.
_BUG_WORDS = ("values to unpack", "math domain error", "operands could not be broadcast",
              "truth value of an array", "zero-size array to reduction operation",
              "arg is an empty sequence")


def _a_bug(err: ValueError) -> bool:
    return any(words in str(err) for words in _BUG_WORDS)


def _internal_error(command: str) -> int:
    """Print the traceback of the exception being handled and say it is a bug; exit 1."""
    traceback.print_exc()
    print(f"inkwarp {command}: internal error (a bug in inkwarp; the traceback above "
          "says where): please report it", file=sys.stderr)
    return 1
