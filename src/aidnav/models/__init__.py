"""Error models and data containers shared by the simulators (:mod:`aidnav.sim`) and the estimators
(:mod:`aidnav.filters`): they describe a sensor or a platform; they neither simulate nor estimate."""
