"""The common shape of every calibration outcome (like scipy's ``OptimizeResult``)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class StepResult:
    """Base of every step's result.

    Attributes
    ----------
    status : str
        ``"ok"``, or a short word for what went wrong (each step documents its own).
    message : str
        One or two sentences for the operator: what was found and what to do about it.
    warnings : list of str
        Things that did not stop the step but that the operator must read.
    """

    status: str
    message: str
    warnings: list = field(default_factory=list)

    @property
    def success(self) -> bool:
        """True when :attr:`status` is ``"ok"``."""
        return self.status == "ok"
