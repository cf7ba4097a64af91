"""One function per `flashbrdf` sub-command; each takes the parsed arguments and returns 0."""
