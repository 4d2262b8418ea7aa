"""A clock tests set by hand: the modules under test take their time source as a callable (or an
object with ``monotonic``), so a test moves time instead of sleeping and a timeout fires when the
test says, however busy the machine is."""


class FakeClock(object):
    def __init__(self, now=0.0):
        self.now = float(now)

    def __call__(self):
        return self.now

    def monotonic(self):
        return self.now

    def advance(self, seconds):
        self.now += seconds
