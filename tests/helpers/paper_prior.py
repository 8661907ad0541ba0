"""The prior of p = (C3, K3) / m3 for the paper's car (C3 = 615 Ns/m, K3 = 98935 N/m, sec. 2.2) and seat
masses m3 in [50, 200] kg, written out from the paper's values: what the networks and objectives are given."""

P_MIN = (615 / 200, 98935 / 200)  # the heaviest seat
P_MAX = (615 / 50, 98935 / 50)  # the lightest
P_SCALE = tuple((a + b) / 2 for a, b in zip(P_MIN, P_MAX))  # the label scale: the range's midpoint
