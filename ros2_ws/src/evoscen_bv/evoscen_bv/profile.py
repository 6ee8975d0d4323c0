"""BV run-time rule profiles: what a learned BV's driver adds around its trained policies.

A learned BV drives with its trained controller and decision policy *and* a few run-time
rules (emergency brake, rule constraints on lane changes, forced merge, who counts as a
leader). How forgiving those rules are is a **profile** (``docs/bv-profiles.md`` explains
every rule and parameter):

* ``driver`` (default): a driver's limits. A vehicle that newly appears ahead in a lane
  (a cut-in) is perceived only after the reaction time; the emergency brake acts only on a
  situation that has persisted for the reaction time; every braking command is bounded by
  a driver's maximum deceleration. A reckless SUT can cause a conflict or a collision.
* ``safety_net``: the rules the shipped policies were trained with (before profiles
  existed): instant reaction to any leader, emergency braking up to the vehicle's full
  brake. Reproduces those runs bit for bit.

Selected per scenario by ``models.learned.profile`` and, for training, by the training
config's ``env.profile`` (recorded in the policy directory's ``training.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass

from .lane_change_decision import CUT_IN_CLOSING_HEADWAY_S

PROFILE_NAMES: tuple[str, ...] = ("driver", "safety_net")
"""Valid profile names; the first is the default."""
DEFAULT_PROFILE = "driver"


@dataclass(frozen=True)
class BVProfile:
    """The parameters of one profile (see ``docs/bv-profiles.md``)."""

    name: str
    reaction_time_s: float
    """τ: a vehicle newly ahead in a lane is perceived, and an emergency situation acted on,
    only after it has persisted for τ (0: at once). In steps: N = round(τ / dt)."""
    max_decel_mps2: float | None
    """Bound on every braking command of the BV (m/s²); ``None``: the vehicle's full brake."""
    cut_in_closing_headway_s: float
    """h of the cut-in gap 10 m + h·closing speed of the lane-change rule constraint (s); 0 = the method's plain 10 m."""
    cut_in_closing_decel_mps2: float | None = None
    """b of the further cut-in gap term c²/(2b), c the closing speed (m/s²): the gap in which the
    slower-to-react vehicle matches speeds braking at b; ``None``: no such term."""
    standing_leader_at_once: bool = False
    """The emergency brake acts at once (without waiting the reaction time) for a perceived
    leader standing still: a vehicle standing in front that the BV has already perceived is
    no surprise (R2, docs/bv-profiles.md). False: the reaction time applies to it too."""

    def reaction_steps(self, dt_s: float) -> int:
        """N = round(τ / dt): steps a situation must persist before the BV responds."""
        return int(round(self.reaction_time_s / dt_s))


PROFILES: dict[str, BVProfile] = {
    # [choice] τ = 1.0 s: highway brake reaction times of alerted-to-surprised drivers are
    # ~0.7-1.5 s (Green 2000, "How long does it take to stop?", Transp. Human Factors 2(3));
    # Treiber & Kesting (Traffic Flow Dynamics, 2013, ch. 12) use ~1 s for human drivers.
    # [choice] 7 m/s²: drivers braking hard for a surprise obstacle reach 0.55-0.7 g (Fambro et
    # al. 1997, NCHRP Report 400), below the simulated car's 8 m/s² full brake; at 6 m/s² the
    # shipped policies' BV-BV collisions rose (docs/bv-profiles.md, measurements).
    # [choice] h = 1.5 s kept: BV-BV realism (docs/bv-profiles.md, measurements).
    # [choice] standing leaders at once: of the BV-BV collisions in queues at the merge, most were a
    # BV starting a lane change from standstill that crept into the vehicle standing 1-2 m ahead in
    # its old lane, its emergency brake waiting the reaction time for a leader it had seen all along
    # (docs/bv-profiles.md, R2); false keeps the earlier rule (models.learned.standing_leader_at_once).
    # [choice] no c²/(2b) term by default: with b = 4 m/s² (MOBIL's b_safe) the merges in front of
    # much faster traffic stopped colliding, but merging BVs waited at standstill and jams formed
    # (4 % of mainline BV states at standstill against 0.3 %); selectable per scenario with
    # models.learned.cut_in_decel_mps2 (docs/bv-profiles.md, R5).
    "driver": BVProfile("driver", reaction_time_s=1.0, max_decel_mps2=7.0,
                        cut_in_closing_headway_s=CUT_IN_CLOSING_HEADWAY_S, standing_leader_at_once=True),
    "safety_net": BVProfile("safety_net", reaction_time_s=0.0, max_decel_mps2=None,
                            cut_in_closing_headway_s=CUT_IN_CLOSING_HEADWAY_S),
}


def get_profile(name: str) -> BVProfile:
    """The profile called ``name`` (ValueError naming the valid ones otherwise)."""
    try:
        return PROFILES[name]
    except KeyError:
        raise ValueError(f"unknown BV profile {name!r}: expected one of {', '.join(PROFILE_NAMES)}") from None
