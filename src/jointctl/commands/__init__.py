"""What a joint is told to do: command sources (step, sine, safe expressions) and the chapter's sine trajectory."""
