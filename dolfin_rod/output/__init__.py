"""What a run writes: time series and summary (writer.py), run folders, checkpoints, run
health (divergence.py), fields along the rod (ParaView, animation)."""
