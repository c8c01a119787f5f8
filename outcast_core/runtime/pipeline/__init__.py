"""The relighting session and the stages that use it: the photo's shadows, depth, relighting,
the automatic sun, time-lapse, batch and the real-photo evaluation."""
