"""Path learning (chapter section 3.2): the route from the guide points, the law that follows
the wall by force, the checks before and after, and the guide-point planner."""
