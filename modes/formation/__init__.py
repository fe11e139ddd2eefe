"""Formation keeping from stream estimates: the simplest follower for role protocols."""
