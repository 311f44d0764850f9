"""The Dask client of a fleet run: a new local cluster, or an existing scheduler.

Failing fast and cleaning up always:

- ``--scheduler ADDR`` is checked before anything is started (:func:`check_scheduler`:
  ``tcp://``, ``tls://``, ``ws://`` or ``wss://`` with ``HOST:PORT``), then probed with a plain
  TCP connection (:data:`PROBE_S`), so an unreachable, closed or unresolvable address is one
  line within seconds; whatever ``distributed`` raises while connecting (a TLS address without
  TLS settings, a server answering garbage) is one line too.
- The local cluster's worker processes inherit a *blocked* SIGINT: Ctrl-C in a terminal
  reaches the whole process group, and it is the client's to handle (cancel, write the rows,
  stop the cluster), not a traceback in every worker.  In the client, a Ctrl-C during the
  start-up is held until the cluster is up (a few seconds) and then stops the run; during
  the shut-down it is held until the workers are stopped, so a second Ctrl-C never cuts the
  clean-up short.
- On the way out, whatever happened, the client and the cluster are closed (bounded by
  :data:`CLOSE_S`) and any worker process this run started that is still alive is
  terminated.
"""
from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import signal
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = ['CLOSE_S', 'CONNECT_S', 'PROBE_S', 'SCHEMES', 'WORKERS_S', 'ClusterError',
           'check_scheduler', 'n_workers', 'open_client']

#: Protocols of ``--scheduler`` (those ``distributed`` speaks over a TCP socket).
SCHEMES = ('tcp', 'tls', 'ws', 'wss')
#: Plain TCP connection to the scheduler's address, before Dask tries [s].
PROBE_S = 3.0
#: Dask's own connection and handshake with the scheduler [s].
CONNECT_S = 5.0
#: Wait for a first worker of an external scheduler [s].
WORKERS_S = 10.0
#: Closing the client, then the cluster, each at most [s].
CLOSE_S = 10.0


class ClusterError(RuntimeError):
    """The Dask cluster could not be started or reached."""


def _shown(addr: str, limit: int = 80) -> str:
    """``addr`` for a one-line message: printable, at most ``limit`` characters."""
    text = addr.encode('utf-8', 'surrogateescape').decode('utf-8', 'backslashreplace')
    text = ''.join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return text if len(text) <= limit else text[:limit - 3] + '...'


def check_scheduler(addr: str) -> tuple[str, str, int]:
    """Check a ``--scheduler`` address; return ``(scheme, host, port)``.

    Parameters
    ----------
    addr : str
        ``SCHEME://HOST:PORT`` (SCHEME one of :data:`SCHEMES`) or ``HOST:PORT`` (tcp).

    Raises
    ------
    ClusterError
        Another protocol, no host, or a port outside 1-65535 (one line).
    """
    scheme, sep, rest = addr.partition('://')
    if not sep:
        scheme, rest = 'tcp', addr
    if scheme not in SCHEMES:
        raise ClusterError(f'--scheduler {_shown(addr)}: protocol {_shown(scheme, 20)}:// is '
                           f'not supported; give tcp://HOST:PORT (or tls, ws, wss)')
    host, colon, port = rest.rpartition(':')
    host = host[1:-1] if host.startswith('[') and host.endswith(']') else host
    if not (colon and host and port.isascii() and port.isdigit() and len(port) <= 5
            and 0 < int(port) < 65536) or any(c in host for c in '/@ ') \
            or not host.isprintable():
        raise ClusterError(f'--scheduler {_shown(addr)}: expected {scheme}://HOST:PORT '
                           f'(PORT 1-65535), e.g. tcp://127.0.0.1:8786')
    return scheme, host, int(port)


def _tcp_problem(host: str, port: int, timeout: float) -> str | None:
    """Why a TCP connection to ``host:port`` fails (None when it opens), within ``timeout``
    (name resolution included: it runs in a daemon thread that is given up on)."""
    result: list[str | None] = []

    def probe() -> None:
        try:
            with socket.create_connection((host, port), timeout=timeout):
                result.append(None)
        except OSError as exc:
            result.append(str(exc.strerror or exc) if not isinstance(exc, TimeoutError)
                          else f'no answer within {timeout:g} s')
        except Exception as exc:  # e.g. UnicodeError of an IDNA host name
            result.append(f'{type(exc).__name__}: {exc}')

    t = threading.Thread(target=probe, name='scheduler-probe', daemon=True)
    t.start()
    t.join(timeout + 1.0)
    return result[0] if result else f'no answer within {timeout:g} s'


def _first_line(exc: BaseException, limit: int = 200) -> str:
    text = f'{type(exc).__name__}: {exc}'.splitlines()[0] if str(exc) else type(exc).__name__
    return _shown(text, limit)


def _connect(Client: Any, addr: str, timeout: float) -> Any:
    """A client of the scheduler at ``addr`` that has at least one worker."""
    _, host, port = check_scheduler(addr)
    hint = (f'start one with `dask scheduler` and workers with `dask worker {_shown(addr)} '
            f'--nthreads 1`')
    problem = _tcp_problem(host, port, PROBE_S)
    if problem is not None:
        raise ClusterError(f'--scheduler {_shown(addr)}: cannot connect ({problem}); {hint}')
    try:
        client = Client(addr, timeout=timeout)
    except Exception as exc:  # distributed's TypeErrors, MemoryError of a garbage answer, ...
        raise ClusterError(f'--scheduler {_shown(addr)}: no Dask scheduler answered '
                           f'({_first_line(exc)}); {hint}') from None
    try:
        client.wait_for_workers(1, timeout=WORKERS_S)
    except Exception:
        with contextlib.suppress(Exception):
            client.close(timeout=CLOSE_S)
        raise ClusterError(
            f'--scheduler {_shown(addr)}: no worker joined within {WORKERS_S:.0f} s; start '
            f'workers with `dask worker {_shown(addr)} --nthreads 1`') from None
    return client


def _start_local(distributed: Any, workers: int | None, processes: bool) -> tuple[Any, Any]:
    """``(cluster, client)`` of a new local cluster of ``workers`` one-thread workers."""
    from inertia_ros.cli.fleet import _cores

    n = workers or _cores()
    # Dask's own log only at CRITICAL: a worker stopped by Ctrl-C or at the end logs its
    # lost heartbeat with a traceback at ERROR; a log a worker cannot finish is a 'failed'
    # row with the error anyway
    # silence_logs only quiets the worker process's 'distributed.nanny' logger: the rest of
    # its 'distributed' log (e.g. "Batched Comm Closed" with a traceback at INFO when Ctrl-C
    # comes during the start-up) follows dask's config, read from the environment when the
    # spawned process imports distributed
    key = 'DASK_LOGGING__DISTRIBUTED'
    saved = os.environ.get(key)
    os.environ[key] = 'critical'
    try:
        cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1,
                                           processes=processes, dashboard_address=None,
                                           silence_logs=logging.CRITICAL)
    except Exception as exc:
        raise ClusterError(f'cannot start a local Dask cluster of {n} workers '
                           f'({_first_line(exc)})') from None
    finally:
        if saved is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = saved
    try:
        return cluster, distributed.Client(cluster)
    except Exception as exc:
        with contextlib.suppress(Exception):
            cluster.close(timeout=CLOSE_S)
        raise ClusterError(f'cannot connect to the local Dask cluster ({_first_line(exc)})'
                           ) from None


@contextlib.contextmanager
def _sigint_held() -> Iterator[None]:
    """Block SIGINT in this thread for the block: a Ctrl-C meanwhile is delivered (and
    raised as KeyboardInterrupt) when the block ends.  Threads and processes started inside
    inherit the blocked signal (the worker processes keep it for their life)."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _stop_children(before: set[Any]) -> None:
    """Terminate (then kill) the child processes started since ``before`` still alive."""
    left = [p for p in multiprocessing.active_children() if p not in before]
    for p in left:
        with contextlib.suppress(Exception):
            p.terminate()
    for p in left:
        with contextlib.suppress(Exception):
            p.join(3.0)
            if p.is_alive():
                p.kill()
                p.join(3.0)


def _shutdown(client: Any, cluster: Any, before: set[Any]) -> None:
    """Close the client and the cluster and stop this run's worker processes, with Ctrl-C
    held until done (a second Ctrl-C never leaves workers behind)."""
    with _sigint_held():
        for thing in (client, cluster):
            if thing is not None:
                with contextlib.suppress(Exception):
                    thing.close(timeout=CLOSE_S)
        _stop_children(before)


def _probe() -> str:
    """Run on each worker: inertia_ros is importable there (returns its location)."""
    import inertia_ros.cli

    return str(Path(inertia_ros.cli.__file__).parent.parent)


@contextlib.contextmanager
def open_client(workers: int | None = None, scheduler: str | None = None,
                connect_timeout: float = CONNECT_S) -> Iterator[Any]:
    """A ``distributed.Client``: on a new local cluster, or on the scheduler at an address.

    Parameters
    ----------
    workers : int, optional
        Local cluster size (one single-threaded worker process each; default: the number of
        CPU cores).  Ignored with ``scheduler``.
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running ``dask scheduler`` (:func:`check_scheduler`).
    connect_timeout : float, optional
        Dask's connection to the scheduler [s].

    Raises
    ------
    ClusterError
        The scheduler cannot be reached, has no worker, or its workers cannot import
        inertia_ros; the local cluster cannot be started.
    KeyboardInterrupt
        Ctrl-C (also one during the start-up, raised once the cluster is up); the cluster
        is stopped first.
    """
    from inertia_ros.fleet import run

    before = set(multiprocessing.active_children())
    made: dict[str, Any] = {'client': None, 'cluster': None}
    if scheduler is None and run.LOCAL_PROCESSES:
        # started now, not by Dask's event loop below: starting it unblocks SIGINT in the
        # starting thread (multiprocessing.resource_tracker), which the worker processes
        # would then inherit
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
    try:
        with _sigint_held():
            # imported here: the threads Dask starts on import (its event loop, which then
            # starts the worker processes) inherit the held SIGINT
            try:
                import distributed
            except ImportError:
                raise ClusterError('fleet needs Dask: pip install dask distributed (pinned in '
                                   'requirements.txt)') from None
            if scheduler is not None:
                made['client'] = _connect(distributed.Client, scheduler, connect_timeout)
            else:
                made['cluster'], made['client'] = _start_local(distributed, workers,
                                                               run.LOCAL_PROCESSES)
        client = made['client']
        try:
            client.run(_probe)
        except Exception as exc:
            raise ClusterError(
                f'the Dask workers cannot import inertia_ros ({_first_line(exc)}); install it '
                'in the workers\' environment') from None
        yield client
    finally:
        _shutdown(made['client'], made['cluster'], before)


def n_workers(client: Any) -> int:
    """Number of workers (worker threads) the client's scheduler has now."""
    info = client.scheduler_info()
    return sum(int(w.get('nthreads', 1)) for w in info.get('workers', {}).values()) or 0
