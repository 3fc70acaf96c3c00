"""The projector output: pixel-exact full-screen patterns, and the display sink a video-input projector takes."""
