"""Files in, validated objects out; files out. No science here."""
