"""Design with exact derivatives: the curves and geometry of the legs optimised by
Ipopt through the differentiable touchdown (:mod:`.optimise`), for an envelope of
touchdowns (:mod:`.robust`), with the NLP compiled to C (:mod:`.compiled_nlp`).

This folder owns design problems and their solves. It must not re-derive the step
or classify touchdowns (the envelope does).
"""
