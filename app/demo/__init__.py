"""The end-to-end demo on the simulated rig and its HTML report (``flexvox demo``)."""
