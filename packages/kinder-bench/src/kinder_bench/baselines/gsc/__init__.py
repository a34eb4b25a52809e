"""Generative skill chaining (GSC; Mishra et al., arXiv 2401.03360) for KinDER.

GSC was never released for KinDER; this is a reconstruction from the public ``gsc-code``
(learning-stack spec §3) adapted to KinDER's skills. The pieces:

* :mod:`.data`: skill transitions ``(s, a, s′)`` with outcome labels, from skill-labelled
  demonstrations (any :class:`~kinder_gym.demos.record.EpisodeRecord` source, or the bilevel
  planner's refined plans via :func:`.data.bp_records`), plus executions of perturbed parameters
  in the env model (the classifier's negatives).
* :mod:`.model`: per (operator, skill) — KinDER pairs each operator with one controller — a
  diffusion ε-model over ``[s, a, s′]`` and a feasibility classifier over ``[s, a]``.
* :mod:`.sampler`: the chained sampler (γ-overlap score composition, inpainting, ranking).
* :mod:`.agent`: the ``gsc`` agent (skeleton from BP's abstract search, BP's skills, re-planning).
* :mod:`.train`: ``kinder train gsc``, with its arguments in :mod:`.config`.

Choices the public code leaves open (or that KinDER forces), all ours:

* **Whole state, arguments first.** A skill's model sees every object of the env's Box view,
  reordered with the operator's arguments first (GSC's ``observation_indices`` idea), not only
  the skill's objects: whether a motion succeeds depends on objects it does not move
  (obstacles, a stick in the way), and with whole states every shared state of a chain is scored
  by both adjacent skills, so no frame assumption is needed. The price: one model per env id
  (fixed object count), as the paper trains per env anyway.
* **Flat residual MLP** instead of GSC's 24-layer object-token DiT (spec §3.3), for CPU budgets.
* **Static features** (never changed by any recorded skill: sizes, colours, fixed geometry) are
  inpainted from the observed state in every chain state, like the objects the skeleton never
  names.
* **Classifier on ``(s, a)``, not on ``s′``.** GSC's classifier scores the effect state alone.
  Here the sampled ``s′`` is the model's own prediction and looks like a success for nearly every
  sample, so scoring it cannot separate good from bad parameters; the classifier instead predicts
  the outcome of executing ``a`` in ``s``, trained on real outcomes (demos and perturbed
  executions), and the ranking is the product over the chain of these probabilities.
* **Sampling defaults**: 50 denoising steps (GSC: 256), 40 samples, γ = 0.5 on every shared
  state, top-1 executed (GSC tries its top 5 with simulator resets; KinDER allows one rollout),
  re-planning from the reached state when a skill fails. No constraint guidance.

Nothing is imported by this ``__init__``: torch loads only when the agent, the sampler or the
trainer is imported, so the command line reads :mod:`.config` without it.
"""
