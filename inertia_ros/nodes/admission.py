"""Input admission for the ``inertia_estimator`` node: which samples reach the estimator.

No rclpy here: the node decodes the polled payloads and hands them over; this module
checks them (frame, NaN/Inf, stamps: zero, out of order, jumps held for confirmation),
counts every refusal per stream, buffers the accepted samples until the next update and
turns the counts into the node's diagnostics (problems and key/values).
"""
from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ['FORWARD_JUMP_NS', 'REFUSED_MIN_SAMPLES', 'REFUSED_WINDOW', 'STAMP_CONFIRM',
           'Admission', 'InputStream']

#: Consecutive samples that confirm a jump of the stamps (else the jumped ones are refused).
STAMP_CONFIRM = 5
#: Smallest forward stamp jump held for confirmation [ns] (clock_jump_threshold if larger).
FORWARD_JUMP_NS = 1_000_000_000
#: Time over which the fraction of refused samples is measured [s].
REFUSED_WINDOW = 1.0
#: Fewest samples over REFUSED_WINDOW for the refused fraction to count.
REFUSED_MIN_SAMPLES = 10
#: Diagnostic levels of the problems (diagnostic_msgs/DiagnosticStatus WARN and ERROR).
WARN, ERROR = b'\x01', b'\x02'


@dataclass
class InputStream:
    """Per-stream bookkeeping: input subscription, counts, newest stamp, pending samples."""

    name: str
    msg_type: str
    field_name: str
    sub: Any = None                       # rclpy Subscription (None: no such stream)
    received: int = 0
    malformed: int = 0
    nan_dropped: int = 0
    out_of_order: int = 0
    refused: int = 0
    bad_stamp: int = 0
    before_gyro: int = 0
    last_ns: int | None = None
    last_rx: float | None = None  # steady clock [s]
    t_ns: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    #: samples whose stamps jumped (kept until confirmed or refused): (t [ns], value (3,))
    pending: list[tuple[int, np.ndarray]] = field(default_factory=list)
    #: per batch over the last second: (steady time [s], received, refused)
    recent: deque[tuple[float, int, int]] = field(default_factory=deque)

    @property
    def topic(self) -> str:
        """The resolved input topic ('' without a subscription)."""
        return self.sub.topic_name if self.sub is not None else ''

    @property
    def refused_total(self) -> int:
        """Samples refused so far: malformed, NaN/Inf, wrong frame, invalid stamp."""
        return self.malformed + self.nan_dropped + self.refused + self.bad_stamp

    def refused_fraction(self, now: float) -> tuple[float, int]:
        """Fraction of the samples received over the last :data:`REFUSED_WINDOW` s that were
        refused, and how many were received."""
        while self.recent and now - self.recent[0][0] > REFUSED_WINDOW:
            self.recent.popleft()
        n = sum(r[1] for r in self.recent)
        bad = sum(r[2] for r in self.recent)
        return (bad / n if n else 0.0), n

    def take(self, epoch_ns: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The buffered samples ([s] since ``epoch_ns`` [ns], values (N, k)), emptied."""
        if not self.t_ns:
            return None
        t = (np.concatenate(self.t_ns) - epoch_ns) * 1e-9
        v = np.concatenate(self.values)
        self.t_ns.clear()
        self.values.clear()
        return t, v


class Admission:
    """Checks, counts and buffers the input samples of the gyro, torque and joint streams.

    Parameters
    ----------
    gyro, torque : InputStream
        The gyro and torque streams (``torque.sub`` None: torque-free, no torque stream).
    joints : InputStream or None
        The JointState stream of the wheels or rotors.
    frame : str or None
        The estimation frame (None: the first gyro message's).
    jump_threshold_s : float
        Stamp jump [s] held for confirmation (``clock_jump_threshold``).
    on_reset : callable
        ``(reason) -> None``: called when a confirmed backward stamp jump must reset the
        estimation (it must call :meth:`clear`).
    logger : object
        ``info`` / ``warning`` with ``throttle_duration_sec`` (an rclpy logger).
    """

    def __init__(self, gyro: InputStream, torque: InputStream, joints: InputStream | None,
                 *, frame: str | None, jump_threshold_s: float,
                 on_reset: Callable[[str], None], logger: Any) -> None:
        self.gyro, self.torque, self.joints = gyro, torque, joints
        self.frame = frame
        self.jump_threshold_s = jump_threshold_s
        self.epoch_ns: int | None = None
        self.last_omega: np.ndarray | None = None
        #: (steady time [s], message) of the last sample refused for its frame
        self.frame_problem: tuple[float, str] | None = None
        self._on_reset = on_reset
        self._log = logger

    # ------------------------------------------------------------------ streams
    def streams(self, timeouts: bool = False) -> tuple[InputStream, ...]:
        """The input streams (with ``timeouts``: those a silence of is a problem)."""
        torque_free = self.torque.sub is None
        out = (self.gyro,) if (timeouts and torque_free) else (self.gyro, self.torque)
        return out + ((self.joints,) if self.joints is not None else ())

    def pending(self) -> bool:
        """Whether any stream has samples waiting for the estimator."""
        return any(s.t_ns for s in self.streams())

    def clear(self) -> None:
        """Forget the buffered samples and the timeline (a reset); counts are kept."""
        for s in self.streams():
            s.t_ns.clear()
            s.values.clear()
            s.last_ns = None  # held samples stay: they may lead the new timeline
        self.epoch_ns = None

    def newest_stamp(self) -> int:
        """The newest accepted gyro or torque stamp [ns]."""
        return max(x for x in (self.gyro.last_ns, self.torque.last_ns) if x is not None)

    def take(self, s: InputStream) -> tuple[np.ndarray, np.ndarray] | None:
        """The buffered samples of ``s`` ([s] since the epoch), emptied."""
        return s.take(self.epoch_ns)

    # ------------------------------------------------------------------ gyro and torque
    def accept(self, s: InputStream, batch: Any, n_payloads: int, now: float) -> None:
        """Check and buffer a decoded batch of ``s`` (:func:`inertia_ros.io.cdr_decode.
        decode_payloads`), counting ``n_payloads`` received messages at steady time ``now``.

        Malformed payloads, NaN/Inf samples, samples from another frame and invalid stamps
        (zero, or further than ``jump_threshold_s`` from the newest stamp without
        :data:`STAMP_CONFIRM` consecutive samples confirming the jump) are refused and
        counted; stamps older than the newest one are dropped as out of order.  A confirmed
        backward jump (bag loop, simulator restart) resets the estimation and starts over at
        that sample; a confirmed forward jump is a gap.
        """
        refused_before = s.refused_total
        try:
            self._accept(s, batch, now)
        finally:
            s.received += n_payloads
            s.last_rx = now
            s.recent.append((now, n_payloads, s.refused_total - refused_before))

    def _admit_frames(self, s: InputStream, batch: Any, ok: np.ndarray, now: float) -> bool:
        """Set the frame from the first gyro message; refuse (in ``ok``) the samples of
        another frame.  False: nothing can be checked yet (torque before the first gyro)."""
        if self.frame is None:
            if s is not self.gyro:
                # The estimation frame is the gyro's: torque before the first gyro
                # message cannot be checked yet (and covers no gyro sample).
                s.before_gyro += int(np.count_nonzero(ok))
                return False
            if ok.any():
                self.frame = batch.frame_ids[batch.frame_index[np.argmax(ok)]]
                self._log.info(f'estimating in frame {self.frame!r} (first gyro message)')
        for k, frame in enumerate(batch.frame_ids):
            if frame != self.frame:
                bad = ok & (batch.frame_index == k)
                n_bad = int(np.count_nonzero(bad))
                if n_bad:
                    s.refused += n_bad
                    ok &= ~bad
                    text = (f'{s.name} frame {frame!r} differs from the estimation frame '
                            f'{self.frame!r}: samples refused')
                    self.frame_problem = (now, text)
                    self._log.warning(text, throttle_duration_sec=5.0)
        return True

    def _accept(self, s: InputStream, batch: Any, now: float) -> None:
        ok = batch.ok.copy()
        s.malformed += int(np.count_nonzero(~ok))
        if not self._admit_frames(s, batch, ok, now):
            return
        values = batch.fields[s.field_name]
        finite = np.all(np.isfinite(values), axis=1)
        s.nan_dropped += int(np.count_nonzero(ok & ~finite))
        ok &= finite
        t_ns = batch.stamp_ns[ok]
        values = values[ok]
        if t_ns.size == 0:
            return
        thr = int(self.jump_threshold_s * 1e9)
        fwd = max(thr, FORWARD_JUMP_NS)
        start = -np.inf if s.last_ns is None else s.last_ns
        prev_max = np.maximum.accumulate(np.concatenate([[start], t_ns[:-1]]))
        ref = np.maximum(prev_max, t_ns[0]) if s.last_ns is None else prev_max
        suspect = (t_ns <= 0) | (ref - t_ns > thr) | (t_ns - ref > fwd)
        if s.pending or suspect.any():
            t_ns, values = self._check_stamps(s, t_ns, values, thr, fwd)
            if t_ns.size == 0:
                return
            prev_max = np.maximum.accumulate(np.concatenate(
                [[-np.inf if s.last_ns is None else s.last_ns], t_ns[:-1]]))
        fresh = t_ns > prev_max
        s.out_of_order += int(np.count_nonzero(~fresh))
        t_ns, values = t_ns[fresh], values[fresh]
        if t_ns.size == 0:
            return
        if self.epoch_ns is None:
            self.epoch_ns = int(t_ns[0])
        s.last_ns = int(t_ns[-1])
        s.t_ns.append(t_ns)
        s.values.append(values)
        if s is self.gyro:
            self.last_omega = values[-1]

    def _check_stamps(self, s: InputStream, t_ns: np.ndarray, values: np.ndarray, thr: int,
                      fwd: int) -> tuple[np.ndarray, np.ndarray]:
        """The slow path of :meth:`accept`: samples with invalid or jumping stamps.

        Returns the samples to go on with (in order; out-of-order ones are dropped by the
        caller).  A zero stamp is always refused.  A stamp more than ``thr`` [ns] behind or
        ``fwd`` [ns] ahead of the newest accepted one is held in ``s.pending``; when
        :data:`STAMP_CONFIRM` consecutive held samples agree (increasing, no jump between
        them), the jump is real: backward resets the estimation, forward is a gap, and the
        held samples are used.  A sample that fits the old timeline again refuses the held
        ones (a glitch), counted in ``bad_stamp``.
        """
        keep_t: list[int] = []
        keep_v: list[np.ndarray] = []
        newest = s.last_ns
        for t, v in zip(t_ns.tolist(), values, strict=True):
            if t <= 0:
                s.bad_stamp += 1
                continue
            if newest is None and s.pending:      # reset meanwhile: the held samples lead
                newest = self._take_pending(s, keep_t, keep_v)
            if newest is None or -thr <= t - newest <= fwd:
                if s.pending:                     # the old timeline goes on: a glitch
                    self._refuse_pending(s)
                keep_t.append(t)
                keep_v.append(v)
                newest = t if newest is None else max(newest, t)
                continue
            if s.pending and not (0 < t - s.pending[-1][0] <= fwd):
                self._refuse_pending(s)           # not even consistent with the held ones
            s.pending.append((t, v))
            if len(s.pending) < STAMP_CONFIRM:
                continue
            jump = (s.pending[0][0] - newest) * 1e-9
            if jump < 0:
                self._on_reset(f'{s.name} stamps jumped back {-jump:.3f} s')
                keep_t.clear()
                keep_v.clear()
            else:
                self._log.info(f'{s.name} stamps jumped ahead {jump:.3f} s: a gap')
            newest = self._take_pending(s, keep_t, keep_v)
        if not keep_t:
            return t_ns[:0], values[:0]
        return np.asarray(keep_t, dtype=np.int64), np.asarray(keep_v, dtype=float)

    @staticmethod
    def _take_pending(s: InputStream, keep_t: list[int], keep_v: list[np.ndarray]) -> int:
        """Move the held samples of ``s`` to the kept ones; the newest stamp [ns]."""
        for t, v in s.pending:
            keep_t.append(t)
            keep_v.append(v)
        s.pending.clear()
        return keep_t[-1]

    def _refuse_pending(self, s: InputStream) -> None:
        """Refuse the held samples of ``s`` (their stamps were a glitch)."""
        s.bad_stamp += len(s.pending)
        self._log.warning(
            f'{s.name}: {len(s.pending)} sample(s) with stamps far from the others refused',
            throttle_duration_sec=5.0)
        s.pending.clear()

    # ------------------------------------------------------------------ joints
    def accept_joints(self, decoded: Sequence[Any], n_payloads: int, joints: Sequence[str],
                      now: float) -> None:
        """Check and buffer decoded JointState messages: the speeds of ``joints``, in order.

        ``decoded`` holds ``(stamp [ns], names, positions, velocities)`` per message, or
        None for a malformed one (refused and counted).  Messages without every joint
        (other joints on the same topic) are skipped; NaN/Inf speeds and zero stamps are
        refused and counted; stamps not after the newest are dropped as out of order.
        Before the first gyro message (no estimation frame yet) samples are dropped, as
        torque samples are.
        """
        s = self.joints
        refused = s.refused_total
        stamps: list[int] = []
        rows: list[np.ndarray] = []
        for msg in decoded:
            if msg is None:
                s.malformed += 1
                continue
            st, names, _pos, vel = msg
            idx = {n: i for i, n in enumerate(names)}
            if len(vel) != len(names) or any(j not in idx for j in joints):
                continue
            v = vel[[idx[j] for j in joints]]
            if not np.all(np.isfinite(v)):
                s.nan_dropped += 1
            elif st <= 0:
                s.bad_stamp += 1
            else:
                stamps.append(st)
                rows.append(v)
        s.received += n_payloads
        s.last_rx = now
        s.recent.append((now, n_payloads, s.refused_total - refused))
        if self.frame is None or self.epoch_ns is None:
            s.before_gyro += len(stamps)
            return
        for st, v in zip(stamps, rows, strict=True):
            if s.last_ns is not None and st <= s.last_ns:
                s.out_of_order += 1
                continue
            s.last_ns = st
            s.t_ns.append(np.array([st], dtype=np.int64))
            s.values.append(v[None, :])

    # ------------------------------------------------------------------ diagnostics
    def problems(self, now: float, *, started: float, timeout: float, refused_limit: float,
                 frame_hold: float, joints_text: str = '') -> list[tuple[bytes, str]]:
        """Input conditions for the diagnostics: (level, message) each.

        Parameters
        ----------
        now, started : float
            Steady time now and at the node's start [s].
        timeout : float
            ``stream_timeout`` [s]: a stream silent longer (or absent that long after the
            start) is a WARN.
        refused_limit : float
            ``max_refused_fraction``: a larger refused fraction over the last second is a WARN.
        frame_hold : float
            How long [s] a refused frame stays an ERROR.
        joints_text : str
            The joints the JointState messages must carry (for the WARN when none does).
        """
        out: list[tuple[bytes, str]] = []
        for s in self.streams(timeouts=True):
            if s.last_rx is None:
                if now - started > timeout:
                    out.append((WARN, f'no {s.name} message on {s.topic} yet'))
            elif now - s.last_rx > timeout:
                out.append((WARN, f'{s.name} stream on {s.topic} silent for '
                            f'{now - s.last_rx:.1f} s (timeout {timeout:g} s)'))
        if self.frame_problem and now - self.frame_problem[0] <= frame_hold:
            out.append((ERROR, self.frame_problem[1]))
        j = self.joints
        if j is not None and j.received and j.last_ns is None and not j.before_gyro:
            out.append((WARN, (f'joints: {j.received} JointState messages on {j.topic}, '
                               f'none with a velocity for every joint of {joints_text}')))
        for s in self.streams():
            frac, n = s.refused_fraction(now)
            if n >= REFUSED_MIN_SAMPLES and frac > refused_limit:
                out.append((WARN, (
                    f'{s.name}: {100 * frac:.0f} % of {n} samples refused over the last '
                    f'{REFUSED_WINDOW:g} s (limit {100 * refused_limit:g} %; so far '
                    f'{s.nan_dropped} NaN/Inf, {s.bad_stamp} invalid stamps, {s.refused} '
                    f'wrong frame, {s.malformed} malformed)')))
        return out

    def counts(self, now: float) -> dict[str, Any]:
        """Per-stream counts and ages [s] for the diagnostics."""
        out: dict[str, Any] = {}
        for s in self.streams():
            out[f'{s.name}_received'] = s.received
            out[f'{s.name}_malformed'] = s.malformed
            out[f'{s.name}_nan_dropped'] = s.nan_dropped
            out[f'{s.name}_out_of_order_dropped'] = s.out_of_order
            out[f'{s.name}_frame_refused'] = s.refused
            out[f'{s.name}_bad_stamp_refused'] = s.bad_stamp
            out[f'{s.name}_refused_fraction'] = s.refused_fraction(now)[0]
        out['torque_before_gyro_dropped'] = self.torque.before_gyro
        for s in self.streams():
            out[f'{s.name}_age_s'] = None if s.last_rx is None else now - s.last_rx
        return out
