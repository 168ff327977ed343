"""Ready-made FE models: simple beams (:mod:`updating.fe.models.beams`) and the GARTEUR
SM-AG19-like aircraft test bed (:mod:`updating.fe.models.garteur`)."""
from updating.fe.models.beams import beam_model, closed_form_hz, thesis_beam, thesis_beam_parameters, timoshenko_pinned_hz

__all__ = ["beam_model", "closed_form_hz", "timoshenko_pinned_hz", "thesis_beam", "thesis_beam_parameters"]
