"""Teaching the guide points without a person's hand: the scripted operator who leads the
robot to each point by pushes (``operator``: the example lead-through, a CSV's points, a
proposal's points, entered on a part off its CAD) and the supervised motion beside the wall for
a point taught by a click (``motion``). The points they record go to path learning
(``robomach_core.learning``)."""
