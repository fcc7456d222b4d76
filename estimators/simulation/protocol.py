r"""One continuous recording of a whole protocol: sensor trajectories joined by smooth transitions.

A clinic that never stops the sensor records the figure-eight, the standing and supine postures and the
motor task in one file per sensor.  :func:`join` builds that sensor's trajectory from the parts' own
*sensor* trajectories (``part.mounted(q_segment_sensor, lever_arm_m)`` for a segment motion, the hand's
trajectory for the figure-eight) so that :func:`estimators.simulation.simulate` (with no further mounting)
gives one recording whose truth says where each part starts and ends.

Between part :math:`k` (ending at pose :math:`q_a, p_a`) and part :math:`k+1` (starting at :math:`q_b, p_b`)
a transition of ``transition_s`` seconds follows the minimum-jerk ramp :math:`s(\tau)` of
:func:`.trajectory.min_jerk`:

.. math:: q(\tau) = \operatorname{slerp}(q_a, q_b, s(\tau)), \qquad p(\tau) = p_a + s(\tau)\,(p_b - p_a),
          \qquad \tau = (t - t_a) / T,

so velocity and acceleration vanish at both ends and the joined trajectory stays C²-smooth where the parts
are at rest at their ends (the postures are; the figure-eight and the step-up begin and end with rests).
The transition stands for strapping the sensor on, lying down and getting up; how a person really does
those is not modelled, only that the sensor moves from one pose to the next without pausing.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from estimators import quaternion as quat
from estimators.simulation.trajectory import Trajectory, min_jerk

FloatArray = NDArray[np.float64]

__all__ = ["join", "leg_protocol"]


def join(parts: Sequence[Trajectory], transition_s: float | Sequence[float] = 6.0) -> tuple[Trajectory, FloatArray]:
    """Join sensor trajectories with minimum-jerk transitions (module docstring).

    parts : the parts' trajectories in recording order, each on a uniform grid of the same rate.
    transition_s : length of each of the ``len(parts) - 1`` transitions, s (one number for all, or one each).
    Returns the joined trajectory (time from 0) and ``spans_s`` (P, 2): each part's ``[start, end]`` on it.
    """
    if len(parts) < 1:
        raise ValueError("join needs at least one trajectory")
    gaps = np.broadcast_to(np.asarray(transition_s, dtype=np.float64), (max(len(parts) - 1, 0),))
    if np.any(~np.isfinite(gaps)) or np.any(gaps <= 0.0):
        raise ValueError(f"transition_s must be positive seconds, got {transition_s!r}")
    dt = float(np.median(np.diff(parts[0].t_s)))
    ts, qs, ps, spans = [], [], [], []
    t0 = 0.0
    for k, part in enumerate(parts):
        t = part.t_s - part.t_s[0] + t0
        spans.append((t[0], t[-1]))
        ts.append(t)
        qs.append(part.q_earth_body)
        ps.append(part.pos_m)
        t0 = t[-1]
        if k + 1 < len(parts):
            n = int(round(gaps[k] / dt))
            tau = np.arange(1, n) / n
            s = min_jerk(tau)
            q_a, q_b = part.q_earth_body[-1], parts[k + 1].q_earth_body[0]
            p_a, p_b = part.pos_m[-1], parts[k + 1].pos_m[0]
            ts.append(t0 + tau * gaps[k])
            qs.append(quat.slerp(q_a, q_b, s))
            ps.append(p_a + s[:, None] * (p_b - p_a))
            t0 += gaps[k]
    joined = Trajectory(np.concatenate(ts), np.concatenate(qs), np.concatenate(ps))
    return joined, np.array(spans, dtype=np.float64)


def leg_protocol(motion, segment: str, q_segment_sensor, *, figure_eight_seed: int | None = 0,
                 posture_s: float = 30.0, figure_eight_s: float = 60.0, transition_s: float = 6.0,
                 ) -> tuple[Trajectory, dict[str, tuple[float, float]]]:
    """One sensor's whole protocol (seed 004 §8.4) as one trajectory: figure-eight in the hand, then strapped to
    ``segment`` (``"thigh"``/``"shank"``) of ``motion``'s leg (a :class:`~estimators.simulation.knee.LegMotion`
    task) with ``q_segment_sensor``: standing, supine, the task; :func:`join`'s transitions between them.

    ``figure_eight_seed=None`` leaves the figure-eight out (factory-calibrated sensors).  Returns the sensor's
    trajectory and the truth ``{role: (start_s, end_s)}``; the figure-eight's span is its motion, without the
    1 s rests at each end of :func:`~estimators.simulation.motions.figure_eight` (the sensor lies still in the hand
    there, as at the start of a transition)."""
    from estimators.simulation.knee import standing, supine
    from estimators.simulation.motions import figure_eight

    lever = motion.thigh_lever_arm_m if segment == "thigh" else motion.shank_lever_arm_m
    parts = [getattr(standing(posture_s, motion.side), segment).mounted(q_segment_sensor, lever),
             getattr(supine(posture_s, motion.side), segment).mounted(q_segment_sensor, lever),
             getattr(motion, segment).mounted(q_segment_sensor, lever)]
    names = ["standing", "lying", "task"]
    if figure_eight_seed is not None:
        parts.insert(0, figure_eight(figure_eight_s, seed=figure_eight_seed))
        names.insert(0, "mag_calibration")
    traj, spans = join(parts, transition_s)
    truth = {n: (float(a), float(b)) for n, (a, b) in zip(names, spans)}
    if figure_eight_seed is not None:
        a, b = truth["mag_calibration"]
        truth["mag_calibration"] = (a + 1.0, b - 1.0)
    return traj, truth
