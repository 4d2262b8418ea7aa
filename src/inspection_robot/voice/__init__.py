"""Voice prompts (robot_voice): VoiceCmd markup to speech and clips, and audio back-ends."""
