"""Measuring a thread: the calibration sheet (:mod:`.sheet`) and reading a photo of it wound (:mod:`.photo`)."""
