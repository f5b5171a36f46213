"""How threads on pins make a picture, and how close it comes: the frame's pins and chords, the thread,
the piece as drawn (the reference rendering), the scores."""
