"""Rendezvous stage (patent step 102): modified Hohmann transfer under J2."""

from ovtraj.rendezvous.hohmann import HohmannTransfer, hohmann, lead_angle
from ovtraj.rendezvous.inputs import rendezvous_input
from ovtraj.rendezvous.result import Impulse, RendezvousInput, RendezvousResult, TransferInput
from ovtraj.rendezvous.stage import circular_transfer, solve_rendezvous

__all__ = [
    "HohmannTransfer",
    "Impulse",
    "RendezvousInput",
    "RendezvousResult",
    "TransferInput",
    "circular_transfer",
    "hohmann",
    "lead_angle",
    "rendezvous_input",
    "solve_rendezvous",
]
