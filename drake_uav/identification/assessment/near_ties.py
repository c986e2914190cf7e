"""Near-tied alternatives: candidates that explain a coefficient almost as well as the
effect the discovery accepted, which the flight therefore cannot tell apart from it."""

from __future__ import annotations

import dataclasses

from drake_uav.identification.discovery.result import DiscoveryResult, Evidence

__all__ = ["NEAR_TIE_MARGIN", "NearTie", "near_ties", "accepted_evidence"]

NEAR_TIE_MARGIN = 0.1
"""Another candidate whose held-out gain on the same coefficient reaches (1 - margin) of the
accepted one's explains the data almost equally well: 10 % of the winner's gain (a winner
at 22.6 % and a rival at 22.1 % are tied; one at 15 % is not)."""


@dataclasses.dataclass(frozen=True)
class NearTie:
    """An accepted candidate and the others that explain its coefficient almost as well.

    Attributes
    ----------
    round : int
        Search round, from 1.
    winner : Evidence
        The accepted candidate's evidence.
    alternatives : tuple of Evidence
        The rivals within :data:`NEAR_TIE_MARGIN` of its held-out gain.
    """

    round: int
    winner: Evidence
    alternatives: tuple[Evidence, ...]

    def summary(self) -> dict:
        """JSON-ready summary of the tie.

        Returns
        -------
        dict
            The round, the coefficient, the accepted effect and its rivals with their held-out
            gains.
        """
        return {"round": self.round, "coefficient": self.winner.coefficient,
                "accepted": self.winner.effect, "pse_reduction": self.winner.pse_reduction,
                "alternatives": [{"effect": e.effect, "pse_reduction": e.pse_reduction,
                                  "passed": bool(e.passed)} for e in self.alternatives]}

    def sentence(self) -> str:
        """One line naming the tie.

        Returns
        -------
        str
            The sentence, for the report.
        """
        rivals = [f"`{e.effect}` ({e.pse_reduction:.2%}"
                  + ("" if e.passed else ", failed the tests") + ")" for e in self.alternatives]
        names = rivals[0] if len(rivals) == 1 else ", ".join(rivals[:-1]) + " and " + rivals[-1]
        verb = "explains" if len(rivals) == 1 else "explain"
        return (f"Round {self.round}: {names} {verb} {self.winner.coefficient} almost as well "
                f"as the accepted `{self.winner.effect}` (held-out gain "
                f"{self.winner.pse_reduction:.2%}): this flight cannot tell them apart.")


def accepted_evidence(discovery: DiscoveryResult) -> set[Evidence]:
    """The evidence of every effect the loop accepted, on every coefficient it entered.

    Parameters
    ----------
    discovery : DiscoveryResult
        The search.

    Returns
    -------
    set of Evidence
        The accepted candidates' evidence.
    """
    return {e for f in discovery.found for e in f.evidence}


def near_ties(discovery: DiscoveryResult, margin: float = NEAR_TIE_MARGIN) -> list[NearTie]:
    """Every accepted candidate that another effect comes close to.

    Another effect on the same coefficient and round whose held-out gain comes within
    ``margin`` of the winner's, passed or not.

    Parameters
    ----------
    discovery : DiscoveryResult
        The search.
    margin : float
        Relative margin of the held-out gain (:data:`NEAR_TIE_MARGIN`).

    Returns
    -------
    list of NearTie
        In the order of the rounds.
    """
    accepted = accepted_evidence(discovery)
    out = []
    for index, evidence in enumerate(discovery.rounds):
        for winner in evidence:
            if winner not in accepted:
                continue
            rivals = tuple(e for e in evidence if e.coefficient == winner.coefficient
                           and e.effect != winner.effect
                           and e.pse_reduction >= (1.0 - margin) * winner.pse_reduction)
            if rivals:
                out.append(NearTie(index + 1, winner, rivals))
    return out
