"""The user pipeline behind ``rmpl run``, stage by stage.

videos -> ``detect2d`` (2D keypoints per view) -> ``association`` (people across views) ->
lifting or triangulation (:mod:`rmpl.inference`, :mod:`rmpl.geometry`) -> ``tracking``
(people over time) -> ``filters`` (gap filling, smoothing) -> files, ``overlay`` videos.
``runner`` chains the stages.
"""
