"""Parts shared by make_log.py and make_families_log.py: a stateful
behaviortreepy action that ends at a drawn time with a drawn status, and
the loop that ticks a tree RUNS times into a FileLogger2 `.btlog`."""
import time

import behaviortreepy as bt


class TimedActions:
    """Stateful actions whose `draw()` gives (success?, duration in s) when
    the node starts; `late` collects how much later than drawn the tree saw
    each completion (tick quantisation)."""

    def __init__(self):
        self.state = {}
        self.late = []

    def callbacks(self, draw):
        """(on_start, on_running, on_halted) of an action drawing `draw()`."""

        def on_start(node):
            ok, d = draw()
            self.state[node.uid()] = (time.monotonic() + d, ok)
            return bt.NodeStatus.RUNNING

        def on_running(node):
            deadline, ok = self.state[node.uid()]
            now = time.monotonic()
            if now < deadline:
                return bt.NodeStatus.RUNNING
            self.late.append(now - deadline)
            return bt.NodeStatus.SUCCESS if ok else bt.NodeStatus.FAILURE

        def on_halted(node):
            self.state.pop(node.uid(), None)

        return on_start, on_running, on_halted

    def late_stats(self):
        """The mean and largest delay, as the truth's JSON fields."""
        return {
            "late_mean_s": sum(self.late) / max(len(self.late), 1),
            "late_max_s": max(self.late, default=0.0),
        }


def run_logged(factory, xml, out, runs):
    """Builds `xml` and ticks it `runs` times, halting it after each run,
    with a FileLogger2 writing `out`."""
    tree = factory.create_tree_from_text(xml)
    logger = bt.FileLogger(tree, out)
    for _ in range(runs):
        # tick without sleeping: the measured duration exceeds the drawn one
        # by less than one tick (a few tens of microseconds)
        while tree.tick_once() == bt.NodeStatus.RUNNING:
            pass
        tree.halt_tree()
    logger.flush()
    del logger
