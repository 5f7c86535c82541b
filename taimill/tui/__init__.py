"""`taimill tui`: a Textual app to tune Ω, the jar speed and friction of a running mill
and watch it respond. The simulation runs in a worker thread (`LiveMill` in short
kernel chunks); widgets hear from it only through the messages of `messages.py`."""
