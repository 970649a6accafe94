"""The executor the nodes spin in: rclpy's EventsExecutor where available.

Measured on 2 cores: the EventsExecutor costs about 1/7 of the SingleThreadedExecutor per
message; a SingleThreadedExecutor falls below real time between 200 and 300 robot nodes of
3 publishers at 10 Hz, the EventsExecutor held 1,000.
"""

from __future__ import annotations

import os
import signal
import threading

import rclpy.executors
import rclpy.utilities
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

#: Wall seconds the EventsExecutor runs its C++ event loop before Python gets control back
#: (to notice a signal, a finished ``until`` or a shut-down context).
SPIN_SLICE_S = 0.25


#: Set by the first SIGINT / SIGTERM of a node process (see :func:`run_node`).
STOP = threading.Event()


def _request_stop(signum, frame) -> None:
    """Signal handler of node processes: note the request, never raise.

    Raising KeyboardInterrupt at an arbitrary bytecode (rclpy's default) can cut a bag write or
    ``metadata.yaml`` in half, and a second Ctrl-C (a terminal's and launch's SIGINT both reach a
    node) would interrupt the cleanup of the first. The spin loop sees the flag within one slice.
    """
    STOP.set()


def install_stop_handlers() -> None:
    """SIGINT and SIGTERM set :data:`STOP` (idempotent; main thread only)."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _request_stop)


def make_executor(context=None, events: bool | None = None):
    """An EventsExecutor (unless ``KILOBOT_TWIN_EXECUTOR=single`` or ``events=False``)."""
    if events is None:
        events = os.environ.get("KILOBOT_TWIN_EXECUTOR", "events") != "single"
    if events:
        try:
            from rclpy.experimental import EventsExecutor

            return EventsExecutor(context=context)
        except ImportError:  # pragma: no cover - older rclpy
            pass
    return rclpy.executors.SingleThreadedExecutor(context=context)


def spin(executor, context=None, until=None) -> None:
    """Spin until ``until`` (a Future) is done or the context shuts down.

    In rclpy 7.1.6 the EventsExecutor's ``spin()`` neither runs timers nor wakes on
    SIGINT/SIGTERM, and ``spin_once()`` returns after every single event (a Python round trip per
    message). ``spin_until_future_complete(future, timeout)`` runs the C++ event loop for a whole
    slice and stops early when the future completes, so we spin in slices of
    :data:`SPIN_SLICE_S`: every message is handled inside the loop, and between slices rclpy's
    signal handling shuts the context down on Ctrl-C / SIGTERM, which ends the loop with
    ExternalShutdownException as with the other executors.
    """
    context = context if context is not None else rclpy.utilities.get_default_context()
    # Each slice adds a done callback to the future it waits on: with nothing to await, a fresh
    # future per slice keeps that list from growing over a long run.
    while context.ok() and not STOP.is_set() and (until is None or not until.done()):
        executor.spin_until_future_complete(until if until is not None else Future(), SPIN_SLICE_S)
    if not context.ok() or STOP.is_set():
        raise rclpy.executors.ExternalShutdownException()


def spin_node(node, until=None) -> None:
    """Spin one node in its own executor until ``until`` is done or the context shuts down."""
    executor = make_executor()
    executor.add_node(node)
    try:
        spin(executor, until=until)
    finally:
        # Let go of the node before anyone destroys it: rclpy's destroy_node waits until no
        # executor uses the node's handles, and an executor dropped while still holding them
        # once kept a world process in destroy_node for a minute after Ctrl-C.
        release(executor, node)


def release(executor, *nodes) -> None:
    """Remove ``nodes`` from ``executor`` and shut the executor down (errors only logged: this runs
    on the way out)."""
    import traceback

    try:
        for node in nodes:
            executor.remove_node(node)
        executor.shutdown(timeout_sec=5.0)
    except Exception:  # noqa: BLE001 - cleanup must go on
        traceback.print_exc()


def run_node(prog: str, make_node, run=spin_node, on_exit=None, args=None) -> None:
    """The life of every node process (the Jazzy pattern, once for all nodes); never returns.

    ``rclpy.init`` without rclpy's signal handlers; SIGINT and SIGTERM (any number of them, also
    to the whole process group, also during the cleanup) only set :data:`STOP`, which ends the
    spin loop (exit code 0: launch reports "finished cleanly"); build the node with
    ``make_node()``; ``run(node)`` (default: spin it); a bad parameter (:class:`ConfigError`)
    ends it with one line and exit code 2, any other error with its traceback and exit code 1;
    ``on_exit(node)`` (e.g. close a bag) and ``destroy_node`` always run, with the context still
    up; then ``rclpy.try_shutdown`` and ``os._exit``: the interpreter's finalisation is skipped
    (it once hung a swarm process for over a minute after its cleanup, in native destructors,
    and it puts SIG_DFL back, so that a late second Ctrl-C killed processes with -SIGINT).
    """
    import faulthandler
    import sys
    import traceback

    from ..errors import ConfigError

    install_stop_handlers()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    code = 0
    try:
        if not STOP.is_set():
            node = make_node()
            run(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    except ConfigError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        code = ConfigError.exit_code
    except BaseException:  # a crash: say where, and exit non-zero after the cleanup
        traceback.print_exc()
        code = 1
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):  # nothing interrupts the cleanup
            signal.signal(sig, signal.SIG_IGN)
        # A cleanup that hangs anyway is reported (every thread's stack) and ended after 60 s.
        faulthandler.dump_traceback_later(60.0, exit=True)
        try:
            if node is not None:
                if on_exit is not None:
                    on_exit(node)
                node.destroy_node()
            rclpy.try_shutdown()
        except BaseException:
            traceback.print_exc()
            code = code or 1
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
