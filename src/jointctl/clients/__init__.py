"""The chapter's clients (prompter, playfile): edges that drive a session's trajectory executor."""
