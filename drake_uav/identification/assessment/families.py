"""Families: an accepted effect and the alternatives this flight cannot tell apart from it.

A finding is one member of a family when other explanations fit the flight as well: its
*aliases*, terms of another physical origin whose columns move with its own (|corr| above
0.95 beyond the rest of the model, :mod:`~drake_uav.identification.discovery.aliases`),
and its *near ties*, candidates whose held-out gain on the same coefficient comes within
10 % of its own (:mod:`~drake_uav.identification.assessment.near_ties`). The report names
the family by the axes of the coefficients the effect is kept on (a "drag-axis family" for
C_D) and lists its members; the finding is then "one of these", and only a flight that
separates them (a logged motor speed, a manoeuvre that moves the distinguishing columns)
can say which. A finding without either is a lone finding.
"""

from __future__ import annotations

import dataclasses

from drake_uav.identification.assessment.near_ties import NEAR_TIE_MARGIN, near_ties
from drake_uav.identification.discovery.result import DiscoveryResult

__all__ = ["AXES", "FamilyMember", "EffectFamily", "families"]

AXES = {"CL": "lift", "CD": "drag", "CY": "side-force", "Cl": "roll", "Cm": "pitch",
        "Cn": "yaw"}
"""Coefficient -> the axis a family on it is named by."""


@dataclasses.dataclass(frozen=True)
class FamilyMember:
    """An alternative of an accepted effect.

    Attributes
    ----------
    name : str
        The alternative: a candidate effect, or ``a change of <baseline term>``.
    correlation : float or None
        |correlation| with the accepted effect's column beyond the rest of the model, when
        it is an alias [-].
    pse_reduction : float or None
        Its held-out gain on the coefficient, when it is a near tie [-].
    """

    name: str
    correlation: float | None = None
    pse_reduction: float | None = None

    def describe(self) -> str:
        """The member for the report.

        Returns
        -------
        str
            ``name`` with why it is a member (its correlation, its held-out gain).
        """
        why = ([f"|corr| {self.correlation:.3f}"] if self.correlation is not None else []) + (
            [f"held-out gain {self.pse_reduction:.2%}"] if self.pse_reduction is not None
            else [])
        return f"`{self.name}` ({', '.join(why)})"


@dataclasses.dataclass(frozen=True)
class EffectFamily:
    """An accepted effect and the members of its family.

    Attributes
    ----------
    effect : str
        The accepted effect.
    coefficients : tuple of str
        The coefficients it is kept on.
    pse_reduction : float
        Its largest held-out gain over them [-].
    members : tuple of FamilyMember
        The alternatives: aliases first (the most correlated first), then the near ties
        that are not aliases (the largest gain first).
    """

    effect: str
    coefficients: tuple[str, ...]
    pse_reduction: float
    members: tuple[FamilyMember, ...]

    @property
    def name(self) -> str:
        """The family's name from its coefficients' axes: ``"drag-axis family"``."""
        axes = list(dict.fromkeys(AXES.get(k, k) for k in self.coefficients))
        joined = axes[0] if len(axes) == 1 else ", ".join(
            f"{a}-" for a in axes[:-1]) + f" and {axes[-1]}"
        return f"{joined}-axis family"

    @property
    def member_names(self) -> tuple[str, ...]:
        """Every name of the family: the accepted effect, then its alternatives."""
        return (self.effect, *(m.name for m in self.members))

    def sentence(self) -> str:
        """One line naming the family and its members, for the report.

        Returns
        -------
        str
            The sentence.
        """
        return (f"{self.name[0].upper()}{self.name[1:]} on {', '.join(self.coefficients)}: "
                f"the accepted `{self.effect}` (held-out gain {self.pse_reduction:.2%}) or "
                + ", ".join(m.describe() for m in self.members)
                + ": this flight cannot tell them apart.")

    def summary(self) -> dict:
        """JSON-ready summary.

        Returns
        -------
        dict
            ``family`` (its name), ``effect``, ``coefficients``, ``pse_reduction`` and
            ``members`` (name, correlation, pse_reduction).
        """
        return {"family": self.name, "effect": self.effect,
                "coefficients": list(self.coefficients), "pse_reduction": self.pse_reduction,
                "members": [dataclasses.asdict(m) for m in self.members]}


def families(discovery: DiscoveryResult, margin: float = NEAR_TIE_MARGIN) -> list[EffectFamily]:
    """The family of every accepted effect that has aliases or near ties.

    Parameters
    ----------
    discovery : DiscoveryResult
        The search.
    margin : float
        Relative margin of a near tie's held-out gain (:data:`NEAR_TIE_MARGIN`).

    Returns
    -------
    list of EffectFamily
        In the order the effects were found; a lone finding has none.
    """
    ties = near_ties(discovery, margin)
    out = []
    for found in discovery.found:
        members = {a.label: FamilyMember(a.label, correlation=a.correlation)
                   for a in discovery.aliases_of(found.name)}
        rivals = sorted((e for t in ties if t.winner.effect == found.name
                         for e in t.alternatives), key=lambda e: -e.pse_reduction)
        for e in rivals:
            if e.effect in members:
                if members[e.effect].pse_reduction is None:
                    members[e.effect] = dataclasses.replace(members[e.effect],
                                                            pse_reduction=e.pse_reduction)
            elif e.effect != found.name:
                members[e.effect] = FamilyMember(e.effect, pse_reduction=e.pse_reduction)
        if members:
            out.append(EffectFamily(found.name, found.coefficients,
                                    max(e.pse_reduction for e in found.evidence),
                                    tuple(members.values())))
    return out
