"""The learning datasets: windows, joint sets, splits and the measures computed on them."""
